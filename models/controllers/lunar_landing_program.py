"""S3 optimal *program* (open loop): full thrust from t_switch to t_off, engine off otherwise.

The control the master reads at ``t_k`` is held over the communication step ``[t_k, t_k + h]``;
on the step that contains ``t_switch`` (or ``t_off``) the FMU outputs the average of the program
over the step, ``u = umax |[t_k, t_k + h] & [t_switch, t_off]| / h`` -- seed 002's averaged
control on the switching step (after Fedorenko), so the switch is not snapped to the grid and the
fuel burnt is exact.  ``h`` is the step size of the last ``doStep`` (the parameter ``step`` before
the first one).

References
----------
Seed 002: T.Yu. Mozzhorina, 2017 (the optimal program: coast, then full thrust; u_avg formula).
"""
from __future__ import annotations

import math

from descent_fmus.models.fmu_support import ParameterError, SlaveBase, require_positive
from descent_fmus.models.lunar_landing import LanderParams, optimal_landing

__all__ = ["program_flow", "LandingProgram"]


def program_flow(t: float, h: float, t_switch: float, t_off: float, umax: float) -> float:
    """Average fuel flow [kg/s] of the program over ``[t, t + h]`` (``h > 0`` [s])."""
    overlap = min(t + h, t_off) - max(t, t_switch)
    return umax * overlap / h if overlap > 0.0 else 0.0


class LandingProgram(SlaveBase):
    """Open-loop optimal program FMU: output ``u`` [kg/s]; no inputs.

    Defaults: the exact optimum of SPEC S3's default scenario (umax = 14.57 kg/s):
    t_switch = 4.734697 s, t_off = T = 16.408339 s.
    """

    description = ("S3 optimal program (open loop): fuel flow umax between t_switch and t_off "
                   "(averaged on the switching step); seed 002, Mozzhorina 2017")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        p = LanderParams()
        opt = optimal_landing(p)
        self.parameter("t_switch", opt.t_switch, "engine-on time [s]")
        self.parameter("t_off", opt.T, "engine-off time (nominal touchdown) [s]")
        self.parameter("umax", p.umax, "fuel flow while on [kg/s]")
        self.parameter("step", 0.01, "communication step assumed before the first doStep [s]")
        self.output("u", "fuel flow averaged over the coming communication step [kg/s]",
                    getter=lambda: program_flow(self._t, self._h, self.t_switch, self.t_off,
                                                self.umax))
        self._t = 0.0
        self._h = self.step
        self.apply_resource_defaults()
        self.prepare()

    def check_parameters(self) -> None:
        for name in ("t_switch", "t_off", "umax", "step"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ParameterError(f"parameter {name} must be finite, got {v!r}")
        require_positive("step", self.step)
        if self.umax < 0.0:
            raise ParameterError(f"parameter umax must be >= 0 kg/s, got {self.umax}")
        if self.t_off < self.t_switch:
            raise ParameterError(f"t_off = {self.t_off} s is before t_switch = "
                                 f"{self.t_switch} s")

    def prepare(self) -> None:
        self._t = 0.0
        self._h = self.step

    def setup_experiment(self, start_time: float, stop_time=None, tolerance=None):
        self._t = float(start_time)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self._t = current_time + step_size
        if step_size > 0.0:
            self._h = step_size
        return True
