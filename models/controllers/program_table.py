"""ProgramController -- plays a computed program u(t), piecewise linear between nodes.

Parameters: ``n_nodes`` (Integer, <= NODES_MAX), the node values ``table[i,j]`` (node ``i`` =
1..n_nodes, channel ``j``) and the node times: ``grid`` = 0 (default) a uniform grid over
``[0, t_end]`` (node ``i`` at ``(i-1) t_end / (n_nodes-1)``), ``grid`` = 1 the times
``t_node[i]`` (increasing; any spacing: e.g. the stages of a traced route joined).
Outputs at the current time ``t``: ``u[j]`` = the interpolated value and ``du[j]`` = the slope of
the segment that starts at ``t`` (0 after the last node; before the first node the first value
is held).

Interface choice (models/README.md): the co-simulation master holds every controller output over
a communication step.  The telescope plants take ``u`` *and* ``du`` and integrate
``u + du (s - t)`` over the step -- a first-order hold -- so the plant sees exactly the
piecewise-linear program the direct method computed, provided every node falls on a
communication point (then every step lies inside one segment).  A plant without a ``du`` input
gets the usual zero-order hold.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2 -- controls sought as piecewise-linear functions of time
("кусочно-линейные управления").
"""
from __future__ import annotations

import bisect
import math

from pythonfmu import Fmi2Causality, Fmi2Variability, Real

from descent_fmus.models.fmu_support import ParameterError, SlaveBase, require_positive

__all__ = ["ProgramController", "NODES_MAX", "N_CHANNELS", "program_values", "evaluate_program"]

#: Capacity of the table (fixed at build time): up to 256 intervals (a traced route of 32
#: stages of 8 intervals).
NODES_MAX = 257
#: Channels (the gimbal rates of S4: up to six gyrodynes).
N_CHANNELS = 6


def evaluate_program(table, n_nodes: int, t_end: float, t: float, times=None):
    """(u, du) of the program at time ``t`` [s]: value and slope of the segment starting at t.

    ``times``: the node times (increasing, ``n_nodes`` of them); default a uniform grid over
    ``[0, t_end]``.
    """
    n_int = n_nodes - 1
    if times is None:
        dt = t_end / n_int
        if t >= t_end - 1e-9 * dt:
            return list(table[n_nodes - 1]), [0.0] * len(table[0])
        i = max(0, min(n_int - 1, int(math.floor(t / dt + 1e-9))))
        s = t - i * dt
    else:
        tol = 1e-9 * (times[n_int] - times[0]) / n_int
        if t >= times[n_int] - tol:
            return list(table[n_nodes - 1]), [0.0] * len(table[0])
        if t < times[0] - tol:
            return list(table[0]), [0.0] * len(table[0])
        i = max(0, min(n_int - 1, bisect.bisect_right(times, t + tol, 0, n_nodes) - 1))
        dt = times[i + 1] - times[i]
        s = t - times[i]
    a, b = table[i], table[i + 1]
    du = [(y - x) / dt for x, y in zip(a, b)]
    return [x + d * s for x, d in zip(a, du)], du


def program_values(t_end: float, controls, times=None) -> dict:
    """Start values of a ProgramController playing ``controls`` (nodes x channels, at most
    N_CHANNELS channels; missing channels are 0) over ``t_end`` on a uniform grid, or at the
    node ``times`` (increasing, one per node; then ``t_end`` is the last of them)."""
    controls = [list(map(float, row)) for row in controls]
    if not 2 <= len(controls) <= NODES_MAX:
        raise ValueError(f"the program needs 2..{NODES_MAX} nodes, got {len(controls)}")
    vals = {"n_nodes": len(controls), "t_end": float(t_end)}
    for i, row in enumerate(controls):
        if not 1 <= len(row) <= N_CHANNELS:
            raise ValueError(f"every node needs 1..{N_CHANNELS} channels, got {len(row)}")
        for j, v in enumerate(row + [0.0] * (N_CHANNELS - len(row))):
            vals[f"table[{i + 1},{j + 1}]"] = v
    if times is not None:
        times = [float(v) for v in times]
        if len(times) != len(controls) or not all(b > a for a, b in zip(times, times[1:])):
            raise ValueError("the node times must be increasing, one per node")
        vals["grid"] = 1
        vals["t_end"] = times[-1]
        vals.update((f"t_node[{i + 1}]", v) for i, v in enumerate(times))
    return vals


class ProgramController(SlaveBase):
    """Plays a piecewise-linear program u(t) (six channels) with its slopes (first-order hold)."""

    description = ("piecewise-linear program u(t) (uniform grid or given node times; values "
                   "and slopes); S4 gimbal-rate programs of the direct method, Voronov 2009")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.int_parameter("n_nodes", 2, f"number of grid nodes in the table (2..{NODES_MAX}) [1]")
        self.parameter("t_end", 40.0, "time of the last node of the uniform grid (grid = 0); "
                       "the first is at t = 0 [s]")
        self.int_parameter("grid", 0, "node times: 0 uniform over [0, t_end], 1 given by "
                           "t_node[i] [1]")
        self.table = [[0.0] * N_CHANNELS for _ in range(NODES_MAX)]
        self.times = [0.0] * NODES_MAX
        names = [f"table[{i + 1},{j + 1}]" for i in range(NODES_MAX) for j in range(N_CHANNELS)]
        tab, times = self.table, self.times

        def getter_of(k):
            return lambda: tab[k // N_CHANNELS][k % N_CHANNELS]

        def setter_of(k):
            def setter(v):
                tab[k // N_CHANNELS][k % N_CHANNELS] = v
            return setter

        def time_setter_of(k):
            def setter(v):
                times[k] = v
            return setter
        self.var_block(Real, names, getter_of, setter_of, causality=Fmi2Causality.parameter,
                       variability=Fmi2Variability.fixed,
                       description="program value of a channel at a node [rad/s]")
        self.var_block(Real, [f"t_node[{i + 1}]" for i in range(NODES_MAX)],
                       lambda k: (lambda: times[k]), time_setter_of,
                       causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                       description="time of a node when grid = 1 (increasing) [s]")
        self.t = 0.0
        self._out = ([0.0] * N_CHANNELS, [0.0] * N_CHANNELS)
        for j in range(N_CHANNELS):
            self.output(f"u[{j + 1}]", f"program value of channel {j + 1} at t [rad/s]",
                        getter=lambda j=j: self._out[0][j])
        for j in range(N_CHANNELS):
            self.output(f"du[{j + 1}]", f"slope of channel {j + 1} on the segment from t "
                        "[rad/s2]", getter=lambda j=j: self._out[1][j])
        self.apply_resource_defaults()
        self.prepare()

    def check_parameters(self) -> None:
        if not 2 <= self.n_nodes <= NODES_MAX:
            raise ParameterError(f"n_nodes must be in 2..{NODES_MAX}, got {self.n_nodes}")
        if self.grid not in (0, 1):
            raise ParameterError(f"grid must be 0 (uniform) or 1 (t_node), got {self.grid}")
        if self.grid == 0:
            require_positive("t_end", self.t_end)
        else:
            ts = self.times[:self.n_nodes]
            if not all(math.isfinite(v) for v in ts) or \
                    not all(b > a for a, b in zip(ts, ts[1:])):
                raise ParameterError("t_node[1..n_nodes] must be finite and increasing")
        for i in range(self.n_nodes):
            for j in range(N_CHANNELS):
                if not math.isfinite(self.table[i][j]):
                    raise ParameterError(f"table[{i + 1},{j + 1}] must be finite")

    def prepare(self) -> None:
        self._update()

    def _update(self):
        if self.grid == 1:
            self._out = evaluate_program(self.table, self.n_nodes, self.t_end, self.t,
                                         self.times)
        elif self.n_nodes >= 2 and self.t_end > 0:
            self._out = evaluate_program(self.table, self.n_nodes, self.t_end, self.t)

    def setup_experiment(self, start_time: float, stop_time=None, tolerance=None):
        self.t = float(start_time)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.t = current_time + step_size
        self._update()
        return True
