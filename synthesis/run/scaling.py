"""Automatic input scaling: the coordinates a law's inputs are searched in, derived from flights.

A law reads its inputs as ``x_scaled = scale * (x - offset)`` (the controller FMU's ``x_scale``,
``x_offset``).  Where a law acts -- where its outputs lie strictly inside their bounds -- its
inputs cover a small part of their range (S1: the near-optimal laws act only while y1 lies in
[0.18, 0.20]); written in coordinates of order 1 there, a polynomial law's coefficients are of
order 1 and act nearly independently, and CMA-ES tunes them far faster than in coordinates where
they are thousands that cancel.  This module finds those coordinates for any problem:

1. fly the problem's basic law from every initial state, recording its inputs and outputs;
2. keep the communication points where the law acts unsaturated (every point if it never does);
3. per input: offset = the middle of its range there, scale = 1 / its half-range;
4. write the basic law in those coordinates -- the same function, exactly: a law linear in its
   parameters (a polynomial, a linear law, a network's output layer) is refitted to itself in the
   new coordinates (:func:`synthesis.methods.structures.fit_parameters`; the fit's residual is
   checked); any other law keeps the coordinates it was given.

The coordinates are refreshed once, where the search has learnt more than the basic law
knew: when the CMA-ES refinement of the basic solution ends, the refined law is flown, its own
acting region measured and the search goes on in those coordinates (:class:`Rescaler`, the
variational GA's ``rescale`` hook).  The scaling is recorded in the run (``scaling.json``, the
summary, and with every exported law, whose ``input_scale``/``input_offset`` are its
coordinates).
"""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.structures import fit_parameters, probe_inputs

__all__ = ["input_window", "rescaled", "auto_scaling", "ScalingError", "Rescaler"]

#: Largest relative residual of the refit that still counts as the same function.
EXACT = 1e-9


class ScalingError(ValueError):
    """The basic law cannot be written in other coordinates (not linear in its parameters)."""


def input_window(law, flights, wiring, margin: float = 1e-9) -> tuple:
    """``(offset, scale)`` per input of ``law`` from recorded ``flights`` (see the module
    docstring); an input that does not vary keeps the law's own offset and scale."""
    xs, acts = [], []
    for r in flights:
        x = np.column_stack([np.asarray(r.outputs[a], float) for a, _ in wiring.to_controller])
        u = np.column_stack([np.asarray(r.outputs["ctrl." + a], float)
                             for a, _ in wiring.to_plant])
        lo = np.array([b[0] for b in law.bounds]) + margin
        hi = np.array([b[1] for b in law.bounds]) - margin
        xs.append(x)
        acts.append(np.any((u > lo) & (u < hi), axis=1))
    x, act = np.vstack(xs), np.concatenate(acts)
    if act.any():
        x = x[act]
    lo, hi = x.min(axis=0), x.max(axis=0)
    half = 0.5 * (hi - lo)
    ok = np.isfinite(half) & (half > 0)
    offset = np.where(ok, 0.5 * (hi + lo), law.input_offset)
    scale = np.where(ok, 1.0 / np.where(ok, half, 1.0), law.input_scale)
    return [float(v) for v in offset], [float(v) for v in scale], int(act.sum())


def rescaled(law, offset, scale):
    """``law`` written in the coordinates ``(offset, scale)``: the same function (ScalingError
    if it is not linear in its parameters, so that no exact rewrite exists)."""
    from descent_fmus.synthesis.methods.law import NetworkOperator
    target = NetworkOperator(law.psi, law.nx, law.q, law.outputs, law.bounds, law.input_names,
                             list(scale), list(offset))
    new = fit_parameters(target, law, points=np.vstack([probe_inputs(target, 128, 1),
                                                         probe_inputs(law, 128, 2)]))
    pts = np.vstack([probe_inputs(target, 64, 3), probe_inputs(law, 64, 4)])
    want = np.array([law.raw(x) for x in pts])
    got = np.array([new.raw(x) for x in pts])
    size = max(float(np.max(np.abs(want))), 1.0)
    if not np.all(np.isfinite(got)) or float(np.max(np.abs(got - want))) > EXACT * size:
        raise ScalingError("the basic law is not linear in its parameters (a polynomial, a "
                           "linear law): it cannot be written in other coordinates exactly")
    return new


def _window(problem, law, plant_fmu, controller_fmu) -> tuple:
    """``(offset, scale, what was derived)`` from flights of ``law`` from every initial state
    (in this process, recorded)."""
    from descent_fmus.synthesis.fmi.loop import open_loop
    from descent_fmus.synthesis.run.signals import critical
    # a stop is raised between the loading and the flights, never inside an FMU's code
    # (synthesis.run.signals)
    loop, flights, sv = None, [], law.start_values()
    try:
        with critical():
            loop = open_loop(problem.wiring, plant_fmu, controller_fmu, native=False)
        for s in problem.initial_states:
            with critical():
                flights.append(loop.run(plant_values=s, controller_values=sv, record=True))
    finally:
        if loop is not None:
            loop.close()
    offset, scale, points = input_window(law, flights, problem.wiring)
    return offset, scale, {"inputs": list(law.input_names), "offset": offset, "scale": scale,
                           "acting_points": points,
                           "points": int(sum(len(r.time) for r in flights))}


def auto_scaling(problem, plant_fmu, controller_fmu) -> tuple:
    """``(problem with its basic law in the derived coordinates, what was derived)``: flies the
    basic law from every initial state in this process (recording) and rewrites it."""
    law = problem.basic()
    offset, scale, info = _window(problem, law, plant_fmu, controller_fmu)
    try:
        new = rescaled(law, offset, scale)
    except ScalingError as exc:
        return problem, dict(info, kept=str(exc), offset=law.input_offset,
                             scale=law.input_scale)
    return problem.with_(basic_law=new), info


class Rescaler:
    """The variational GA's ``rescale`` hook: the refined basic law in the coordinates where
    it acts (None if it cannot be rewritten, or its parameters would leave the Gray code's
    range ``(lo, hi)``); what it derived is kept in :attr:`refreshes`."""

    def __init__(self, problem, plant_fmu, controller_fmu, q_range: tuple):
        self.problem, self.fmus, self.q_range = problem, (plant_fmu, controller_fmu), q_range
        self.refreshes: list = []

    def __call__(self, law):
        offset, scale, info = _window(self.problem, law, *self.fmus)
        try:
            new = rescaled(law, offset, scale)
        except ScalingError as exc:
            self.refreshes.append(dict(info, kept=str(exc)))
            return None
        lo, hi = self.q_range
        if not all(lo <= v < hi for v in new.q):
            self.refreshes.append(dict(info, kept="its parameters leave the Gray code's range"))
            return None
        self.refreshes.append(info)
        return new
