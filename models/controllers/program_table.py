"""ProgramController -- plays a computed program u(t), piecewise linear on a uniform grid.

Parameters: ``n_nodes`` (Integer, <= NODES_MAX), ``t_end`` [s] and the node values
``table[i,j]`` (node ``i`` = 1..n_nodes at ``t = (i-1) t_end / (n_nodes-1)``, channel ``j``).
Outputs at the current time ``t``: ``u[j]`` = the interpolated value and ``du[j]`` = the slope of
the segment that starts at ``t`` (0 after ``t_end``).

Interface choice (models/README.md): the co-simulation master holds every controller output over
a communication step.  The telescope plants take ``u`` *and* ``du`` and integrate
``u + du (s - t)`` over the step -- a first-order hold -- so the plant sees exactly the
piecewise-linear program the direct method computed, provided the communication step divides
the grid spacing (then every step lies inside one segment).  A plant without a ``du`` input gets
the usual zero-order hold.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2 -- controls sought as piecewise-linear functions of time
("кусочно-линейные управления").
"""
from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Variability, Real

from descent_fmus.models.fmu_support import ParameterError, SlaveBase, require_positive

__all__ = ["ProgramController", "NODES_MAX", "N_CHANNELS", "program_values", "evaluate_program"]

#: Capacity of the table (fixed at build time): up to 120 intervals.
NODES_MAX = 121
#: Channels (the six gimbal rates of S4).
N_CHANNELS = 6


def evaluate_program(table, n_nodes: int, t_end: float, t: float):
    """(u, du) of the program at time ``t`` [s]: value and slope of the segment starting at t."""
    n_int = n_nodes - 1
    dt = t_end / n_int
    if t >= t_end - 1e-9 * dt:
        return list(table[n_nodes - 1]), [0.0] * len(table[0])
    i = max(0, min(n_int - 1, int(math.floor(t / dt + 1e-9))))
    s = t - i * dt
    a, b = table[i], table[i + 1]
    du = [(y - x) / dt for x, y in zip(a, b)]
    return [x + d * s for x, d in zip(a, du)], du


def program_values(t_end: float, controls) -> dict:
    """Start values of a ProgramController playing ``controls`` (nodes x channels) over t_end."""
    controls = [list(map(float, row)) for row in controls]
    if not 2 <= len(controls) <= NODES_MAX:
        raise ValueError(f"the program needs 2..{NODES_MAX} nodes, got {len(controls)}")
    vals = {"n_nodes": len(controls), "t_end": float(t_end)}
    for i, row in enumerate(controls):
        if len(row) != N_CHANNELS:
            raise ValueError(f"every node needs {N_CHANNELS} channels, got {len(row)}")
        for j, v in enumerate(row):
            vals[f"table[{i + 1},{j + 1}]"] = v
    return vals


class ProgramController(SlaveBase):
    """Plays a piecewise-linear program u(t) (six channels) with its slopes (first-order hold)."""

    description = ("piecewise-linear program u(t) on a uniform grid (values and slopes); "
                   "S4 gimbal-rate programs of the direct method, Voronov 2009")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.int_parameter("n_nodes", 2, f"number of grid nodes in the table (2..{NODES_MAX}) [1]")
        self.parameter("t_end", 40.0, "time of the last node; the first is at t = 0 [s]")
        self.table = [[0.0] * N_CHANNELS for _ in range(NODES_MAX)]
        names = [f"table[{i + 1},{j + 1}]" for i in range(NODES_MAX) for j in range(N_CHANNELS)]
        tab = self.table

        def getter_of(k):
            return lambda: tab[k // N_CHANNELS][k % N_CHANNELS]

        def setter_of(k):
            def setter(v):
                tab[k // N_CHANNELS][k % N_CHANNELS] = v
            return setter
        self.var_block(Real, names, getter_of, setter_of, causality=Fmi2Causality.parameter,
                       variability=Fmi2Variability.fixed,
                       description="program value of a channel at a node [rad/s]")
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
        require_positive("t_end", self.t_end)
        for i in range(self.n_nodes):
            for j in range(N_CHANNELS):
                if not math.isfinite(self.table[i][j]):
                    raise ParameterError(f"table[{i + 1},{j + 1}] must be finite")

    def prepare(self) -> None:
        self._update()

    def _update(self):
        if self.n_nodes >= 2 and self.t_end > 0:
            self._out = evaluate_program(self.table, self.n_nodes, self.t_end, self.t)

    def setup_experiment(self, start_time: float, stop_time=None, tolerance=None):
        self.t = float(start_time)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.t = current_time + step_size
        self._update()
        return True
