"""The on-board predictions of S1's guidance controllers in C, traced from their one Python definition.

The native ``GuidedNetworkOperatorController`` (``c/guided_model.c``) and ``ReentryNPC``
(``c/npc_model.c``) run the guidance cycle of :mod:`models.controllers.reentry_npc` -- every
cycle, the correction c (the guided law) or the constant control u (the NPC) whose predicted
flight lands at Lf.  Their loops (the prediction's steps, Brent's root search, ``c/brent.h``)
are written in C once; the arithmetic inside them is traced from the Python functions of
:mod:`models.controllers.reentry_prediction` here, into the same C unit as the controller's
estimator (:mod:`.sensing`).  Of the guided law (:func:`trace_guidance`):

* ``<prefix>_geometry(r, iv, in, out)`` -- :func:`~models.controllers.reentry_prediction.
  predicted_inputs` at the state ``in[0..3]`` on the line from ``h0_line`` (``in[4]``:
  log factor, ``in[5]``: dlam, ``in[6]``: h_now) -> y1, y2, y3, and
  :func:`models.reentry.altitude` of the state -> out[3];
* ``<prefix>_corrected(r, iv, in, out)`` -- the controller's ``_corrected(u, c, x, kd, model)``
  (``in``: u, c, x1..x4, kd, the model's lam) -> the corrected, clipped control;
* ``<prefix>_step(r, iv, in, out)`` -- :func:`~models.controllers.reentry_prediction.
  predict_step` (``in``: x1..x4, u, kd, lam, dt) -> the state, the outcome (0 OK, 1 EVENT,
  2 DIVERGED) and, at the EVENT, the down-range :func:`models.reentry.downrange` (else 0);
* ``<prefix>_load(r, iv, in, out)`` -- :func:`~models.controllers.reentry_prediction.
  predicted_load` (``in``: x1..x4, u, kd, lam): the load the prediction samples and the
  re-planner's floor;
* ``<prefix>_plan(r, iv, in, out)`` -- :func:`~models.controllers.reentry_replan.plan_value`
  (``in``: the K weights, the altitude): the re-planned correction.

Of the NPC (:func:`trace_npc`):

* ``<prefix>_altitude(r, iv, in, out)`` -- :func:`models.reentry.altitude` of ``in[0..3]``;
* ``<prefix>_range(r, iv, in, out)`` -- :func:`~models.controllers.reentry_prediction.
  predict_range` with a constant control (``in``: x1..x4, u, kd, lam, dt): the predicted
  down-range at hf.

:func:`guidance_constants` gives the C the nominal model's numbers it needs (lam, Lf, hf, the
horizon, the range of a flight that does not reach hf).
"""
from __future__ import annotations

from descent_fmus.models.controllers.reentry_prediction import (HORIZON, NOT_REACHED, predict_range,
                                                                predict_step, predicted_inputs,
                                                                predicted_load)
from descent_fmus.models.controllers.reentry_replan import (FD_STEP, MISS_SCALE, PLAN_KNOTS,
                                                            plan_value)
from descent_fmus.models.integrators import DIVERGED, EVENT, OK
from descent_fmus.models.reentry import U_BOUNDS, ReentryParams, altitude, downrange
from descent_fmus.synthesis.fmi.native.tracer.plant_codegen import literal
from descent_fmus.synthesis.fmi.native.tracer.plant_trace import Tracer, explore

__all__ = ["trace_guidance", "trace_npc", "guidance_constants", "OUTCOMES"]

#: the outcome codes of ``<prefix>_step`` (models.integrators' OK, EVENT, DIVERGED)
OUTCOMES = {OK: 0, EVENT: 1, DIVERGED: 2}


def _signature(name: str) -> str:
    return f"int {name}(const double *r, const int *iv, const double *in, double *out)"


def _writes(value, scope, ind):
    return [f"{ind}out[{k}] = {scope.value(v)};" for k, v in enumerate(value)] + \
        [f"{ind}return PC_OK;"]


def _trace(code, stem: str, body) -> None:
    from descent_fmus.synthesis.fmi.native.tracer.plant_trace import operand
    tracer = Tracer(f"{code.prefix} {stem}")
    tree = explore(tracer, lambda: [operand(v) for v in body(tracer)])
    code._function(stem, _signature("@NAME@"), ("r", "iv", "in", "out"), tracer, tree,
                   _writes, {code.code.R: "r", code.code.I: "iv", code.IN: "in"})


def trace_guidance(code) -> None:
    """Trace the three functions (module docstring) into the unit of ``code``, a
    :class:`~.sensing.SensingCode` of the guided controller class (its instance's parameters
    bound to the FMU's arrays)."""
    inst, IN = code.code.inst, code.IN
    model = ReentryParams()

    def geometry(tracer):
        x = tuple(IN.sym(k) for k in range(4))
        line = ReentryParams(h0=inst.h0_line)
        y = predicted_inputs(x, line, model.Rz, IN.sym(4), IN.sym(5), IN.sym(6))
        return list(y) + [altitude(x, model.Rz)]

    def corrected(tracer):
        x = tuple(IN.sym(2 + k) for k in range(4))
        return [inst._corrected(IN.sym(0), IN.sym(1), x, IN.sym(6),
                                model.with_(lam=IN.sym(7)))]

    def step(tracer):
        x, outcome = predict_step(tuple(IN.sym(k) for k in range(4)), IN.sym(4), IN.sym(5),
                                  IN.sym(6), model, IN.sym(7))
        rng = downrange(x, model.Rz) if outcome == EVENT else 0.0
        return list(x) + [float(OUTCOMES[outcome]), rng]

    def load(tracer):
        return [predicted_load(tuple(IN.sym(k) for k in range(4)), IN.sym(4), IN.sym(5),
                               IN.sym(6), model)]

    def plan(tracer):
        return [plan_value([IN.sym(k) for k in range(len(PLAN_KNOTS))],
                           IN.sym(len(PLAN_KNOTS)))]

    for stem, body in (("geometry", geometry), ("corrected", corrected), ("step", step),
                       ("load", load), ("plan", plan)):
        _trace(code, stem, body)


def trace_npc(code) -> None:
    """Trace the NPC's two functions (module docstring) into the unit of ``code``, a
    :class:`~.sensing.SensingCode` of ``ReentryNPC``."""
    IN, model = code.IN, ReentryParams()

    def height(tracer):
        return [altitude(tuple(IN.sym(k) for k in range(4)), model.Rz)]

    def range_(tracer):
        return [predict_range(tuple(IN.sym(k) for k in range(4)), IN.sym(4), IN.sym(5), model,
                              IN.sym(7), IN.sym(6))]

    for stem, body in (("altitude", height), ("range", range_)):
        _trace(code, stem, body)


def guidance_constants(prefix: str) -> dict:
    """``model_config.h`` constants of the nominal model the guidance predicts with."""
    m = ReentryParams()
    return {"GUIDE_LAM": literal(m.lam), "GUIDE_LF": literal(m.Lf), "GUIDE_HF": literal(m.hf),
            "GUIDE_KD": literal(m.constants()[1]), "GUIDE_HORIZON": literal(HORIZON),
            "GUIDE_NOT_REACHED": literal(NOT_REACHED),
            "GUIDE_GEOMETRY": f"{prefix}_geometry", "GUIDE_CORRECTED": f"{prefix}_corrected",
            "GUIDE_STEP": f"{prefix}_step", "GUIDE_ALTITUDE": f"{prefix}_altitude",
            "GUIDE_RANGE": f"{prefix}_range", "GUIDE_U_MIN": literal(U_BOUNDS[0]),
            "GUIDE_U_MAX": literal(U_BOUNDS[1]), "GUIDE_LOAD": f"{prefix}_load",
            "GUIDE_PLAN": f"{prefix}_plan", "PLAN_K": len(PLAN_KNOTS),
            "PLAN_FD_STEP": literal(FD_STEP), "PLAN_MISS_SCALE": literal(MISS_SCALE)}
