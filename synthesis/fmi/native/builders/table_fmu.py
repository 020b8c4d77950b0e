"""Program tables as native FMUs: one hand-written table player (``table_model.c``) for all.

* :func:`build_program_fmu` -- a piecewise-linear program on a uniform grid with its slopes,
  the variables of the pythonfmu ``ProgramController`` (``n_nodes``, ``t_end``, ``table[i,j]``,
  outputs ``u[j]``, ``du[j]``) sized to the program: the S4 gimbal-rate programs of the direct
  method and the S1 open-loop program would play with linear ramps).  Its player is the one of
  the native ``ProgramController`` (:mod:`.controllers`), which also has ``grid``/``t_node``.
* :func:`build_step_program_fmu` -- a piecewise-constant program between breakpoints whose
  output is its mean over the coming communication step (the pythonfmu ``LandingProgram``'s
  averaged control): the S3 landing program is the table ``t = (0, t_switch, t_off)``,
  ``u = (0, umax, 0)`` with the output named ``u`` (:func:`landing_program_fmu`); the S1
  open-loop program ``u[k]`` on segments of ``t_seg`` is :func:`hold_program_fmu`.

Both are sampled controllers like every controller of the project (``sample_period``).
"""
from __future__ import annotations

import math
from pathlib import Path

from descent_fmus.models.fmu_support import SAMPLE_PERIOD_DESCRIPTION
from descent_fmus.synthesis.fmi.native.builders.build import Variable, build_fmu
from descent_fmus.synthesis.fmi.native.builders.ccode import c_identifier
from descent_fmus.synthesis.fmi.native.builders.controllers import program_layout

__all__ = ["build_program_fmu", "build_step_program_fmu", "landing_program_fmu",
           "hold_program_fmu", "program_of_start_values"]


def _table(rows, what: str) -> list:
    rows = [[float(v) for v in row] for row in rows]
    if not rows or any(len(r) != len(rows[0]) for r in rows) or not rows[0]:
        raise ValueError(f"{what}: the table must be a non-empty matrix (nodes x channels)")
    if not all(math.isfinite(v) for r in rows for v in r):
        raise ValueError(f"{what}: the table must hold finite values")
    return rows


def _per_second(unit: str) -> str:
    """``unit`` / s in the FMI spelling (``1/s``, ``rad/s2``, ``kg/s``)."""
    if unit == "1":
        return "1/s"
    num, _, den = unit.partition("/")
    if not den:
        return f"{unit}/s"
    if den == "s":
        return f"{num}/s2"
    if den.startswith("s") and den[1:].isdigit():
        return f"{num}/s{int(den[1:]) + 1}"
    return f"{num}/{den}.s"


def _step_config(nodes: int, channels: int) -> dict:
    return {"model_config.h": "/* the table's kind and size for table_model.c (generated) */\n"
                              f"#define TABLE_KIND 1\n#define TABLE_NODES {nodes}\n"
                              f"#define TABLE_CHANNELS {channels}\n"}


def build_program_fmu(dest, t_end: float, controls, identifier: str = "ProgramTable",
                      description: str = "", unit: str = "1") -> Path:
    """A piecewise-linear program u(t) (``controls``: nodes x channels over [0, t_end]) as a
    native FMU with the ProgramController's variables; outputs in ``unit``."""
    rows = _table(controls, "program")
    if len(rows) < 2 or not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"a program needs >= 2 nodes and t_end > 0, got {len(rows)} nodes, "
                         f"t_end = {t_end}")
    n, c = len(rows), len(rows[0])
    variables = [Variable(f"u[{j + 1}]", "output", 0.0, f"program value of channel {j + 1} "
                          f"at t [{unit}]") for j in range(c)]
    variables += [Variable(f"du[{j + 1}]", "output", 0.0, f"slope of channel {j + 1} on the "
                           f"segment from t [{_per_second(unit)}]") for j in range(c)]
    variables.append(Variable("t_end", "fixed", t_end, "time of the last node; the first is "
                              "at t = 0 [s]"))
    variables += [Variable(f"table[{i + 1},{j + 1}]", "fixed", v, f"program value of a channel "
                           f"at a node [{unit}]") for i, row in enumerate(rows)
                  for j, v in enumerate(row)]
    variables.append(Variable("sample_period", "fixed", 0.0, SAMPLE_PERIOD_DESCRIPTION))
    variables.append(Variable("n_nodes", "fixed", n, f"number of grid nodes in the table "
                              f"(2..{n}) [1]", type="Integer"))
    ident = c_identifier(identifier)
    config = {"model_config.h": program_layout(variables, n, c, grid=False)}
    return build_fmu(dest, ident, description or "piecewise-linear program u(t) on a uniform "
                     "grid (values and slopes)", variables, config,
                     ["table_model.c"], experiment={"startTime": 0.0, "stopTime": t_end})


def build_step_program_fmu(dest, times, values, identifier: str = "StepProgram",
                           outputs=None, step: float = 1.0, description: str = "",
                           unit: str = "1") -> Path:
    """A piecewise-constant program (row i of ``values`` from ``times[i]`` to ``times[i+1]``,
    the last row for ever) whose outputs are its mean over the coming communication step, as a
    native FMU; ``outputs`` names the channels (default ``u[1]``, ...), ``step`` is the step
    assumed before the first one."""
    rows = _table(values, "step program")
    times = [float(t) for t in times]
    if len(times) != len(rows) or any(not math.isfinite(t) for t in times) \
            or any(b < a for a, b in zip(times, times[1:])):
        raise ValueError("a step program needs one finite, non-decreasing breakpoint per row")
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be > 0 s, got {step}")
    n, c = len(rows), len(rows[0])
    names = list(outputs) if outputs else [f"u[{j + 1}]" for j in range(c)]
    if len(names) != c:
        raise ValueError(f"{c} channels but {len(names)} output names")
    variables = [Variable(name, "output", 0.0, f"program averaged over the coming "
                          f"communication step [{unit}]") for name in names]
    variables += [Variable(f"t[{i + 1}]", "fixed", t, "breakpoint: row i holds from t[i] "
                           "[s]") for i, t in enumerate(times)]
    variables += [Variable(f"table[{i + 1},{j + 1}]", "fixed", v, f"program value from t[i] "
                           f"[{unit}]") for i, row in enumerate(rows) for j, v in enumerate(row)]
    variables.append(Variable("step", "fixed", step, "communication step assumed before the "
                              "first doStep [s]"))
    variables.append(Variable("sample_period", "fixed", 0.0, SAMPLE_PERIOD_DESCRIPTION))
    variables.append(Variable("n_nodes", "fixed", n, f"number of rows in use (1..{n}) [1]",
                              type="Integer"))
    return build_fmu(dest, c_identifier(identifier), description or "piecewise-constant program "
                     "averaged over the coming communication step", variables,
                     _step_config(n, c), ["table_model.c"])


def landing_program_fmu(dest, t_switch: float, t_off: float, umax: float, step: float,
                        identifier: str = "LandingProgramTable") -> Path:
    """The S3 optimal program (engine off, ``umax`` from ``t_switch`` to ``t_off``, off) as a
    native step program with the output ``u`` [kg/s], for the LandingProgram's wiring."""
    return build_step_program_fmu(dest, (0.0, t_switch, t_off), ((0.0,), (umax,), (0.0,)),
                                  identifier, outputs=["u"], step=step, unit="kg/s",
                                  description="S3 optimal program (open loop): fuel flow umax "
                                              "between t_switch and t_off, averaged on the "
                                              "switching step; Mozzhorina 2017")


def program_of_start_values(values: dict) -> tuple[float, list]:
    """``(t_end, controls)`` of ProgramController start values (``n_nodes``, ``t_end``,
    ``table[i,j]``): the program a native program FMU plays the same way."""
    n = int(values["n_nodes"])
    channels = sum(1 for k in values if k.startswith("table[1,"))
    return float(values["t_end"]), [[float(values[f"table[{i},{j}]"])
                                     for j in range(1, channels + 1)] for i in range(1, n + 1)]


def hold_program_fmu(dest, t_seg: float, u, identifier: str = "HoldProgram",
                     output: str = "u[1]") -> Path:
    """A program ``u(t) = u[k]`` for ``k t_seg <= t < (k+1) t_seg`` (the last value after
    the end; the S1 open-loop program, ``synthesis.systems.reentry.bound.Program``) as a native
    step program: flown with communication step ``t_seg`` it sets ``u[k]`` on segment k."""
    u = [float(v) for v in u]
    return build_step_program_fmu(dest, [k * t_seg for k in range(len(u))], [[v] for v in u],
                                  identifier, outputs=[output], step=t_seg,
                                  description="piecewise-constant open-loop program u(t)")
