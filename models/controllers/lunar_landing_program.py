"""S3 optimal *program* (open loop): full thrust from t_switch to t_off, engine off otherwise.

The control the master reads at ``t_k`` is held over the communication step ``[t_k, t_k + h]``;
on the step that contains ``t_switch`` (or ``t_off``) the FMU outputs the average of the program
over the step, ``u = umax |[t_k, t_k + h] & [t_switch, t_off]| / h`` -- Mozzhorina's averaged
control on the switching step (after Fedorenko), so the switch is not snapped to the grid and the
fuel burnt is exact.  ``h`` is the step size of the last ``doStep`` (the parameter ``step`` before
the first one).

References
----------
T.Yu. Mozzhorina, 2017 (the optimal program: coast, then full thrust; the averaged control).
"""
from __future__ import annotations

from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.lunar_landing import STEP, LanderParams
from descent_fmus.models.params import ParameterError, Params, param

__all__ = ["ProgramParams", "program_flow", "LandingProgram"]


@dataclass(frozen=True)
class ProgramParams(Params):
    """Parameters of the program FMU; defaults = the exact optimum of the default scenario.

    ``t_switch`` and ``t_off`` are ``models.lunar_landing.optimal_landing()`` for
    :class:`~models.lunar_landing.LanderParams` ``()`` to the last bit (a test checks it); the
    closed loop ``LunarLanderProgramClosedLoop`` gets its values computed when it is built.
    """

    t_switch: float = param(4.734697455625762, "s", "engine-on time")
    t_off: float = param(16.40833852799481, "s", "engine-off time (nominal touchdown)")
    umax: float = param(LanderParams.umax, "kg/s", "fuel flow while on")
    step: float = param(STEP, "s", "communication step assumed before the first doStep",
                        positive=True)

    def check(self) -> None:
        if self.umax < 0.0:
            raise ParameterError(f"parameter umax must be >= 0 kg/s, got {self.umax}")
        if self.t_off < self.t_switch:
            raise ParameterError(f"t_off = {self.t_off} s is before t_switch = "
                                 f"{self.t_switch} s")


def program_flow(t: float, h: float, t_switch: float, t_off: float, umax: float) -> float:
    """Average fuel flow [kg/s] of the program over ``[t, t + h]``.

    Parameters
    ----------
    t : float
        Start of the step [s].
    h : float
        Step size [s], > 0.
    t_switch, t_off : float
        Engine-on and engine-off times [s].
    umax : float
        Fuel flow while on [kg/s].
    """
    overlap = min(t + h, t_off) - max(t, t_switch)
    return umax * overlap / h if overlap > 0.0 else 0.0


class LandingProgram(SlaveBase):
    """Open-loop optimal program FMU: output ``u`` [kg/s]; no inputs.

    Defaults (:class:`ProgramParams`): the exact optimum of the default scenario
    (umax = 14.57 kg/s): t_switch = 4.734697 s, t_off = T = 16.408339 s.
    """

    params_class = ProgramParams

    description = ("S3 optimal program (open loop): fuel flow umax between t_switch and t_off "
                   "(averaged on the switching step); Mozzhorina 2017")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.output("u", "fuel flow averaged over the coming communication step [kg/s]",
                    getter=lambda: program_flow(self._t, self._h, self.t_switch, self.t_off,
                                                self.umax))
        self._t = 0.0
        self._h = self.step
        self.apply_resource_defaults()
        self.prepare()

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
