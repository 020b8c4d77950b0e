"""S2 -- the Bellman/averaging angle-of-attack law of Lyubimov & Kurkina (eq. 17).

    u = sat_{u_max}( A alpha cos(theta + theta1) / (2 c omega_a) )

``A`` is the positive root of the averaged Bellman equation (eq. 14, divided by eps alpha^2)::

    b - A omega omega_dot / omega_a^2 - A^2 / (8 c omega_a^2) = 0

* ``formula = 0`` (default) -- the consistent root::

      A = 4 c omega_a^2 ( -omega omega_dot / omega_a^2
                          + sqrt(omega^2 omega_dot^2 / omega_a^4 + b / (2 c omega_a^2)) )

  positive for every ``omega_dot``; it is evaluated in a cancellation-free form.
* ``formula = 1`` -- the paper's printed root (15) with its conditions (16)::

      A = 8 c omega_a^2 ( -omega omega_dot / omega_a^2 + sqrt(D) ),
      D = omega^2 omega_dot^2 / omega_a^4 - b / (4 c omega_a^2)

  and u = 0 where ``omega_dot >= 0`` or ``D < 0`` (the paper's guards).  This root does not
  solve eq. (14) (a sign and a factor under the root are off); kept to compare.

The functions below are the one implementation of the law: the :class:`MarsBellmanController`
FMU and the in-process code (tests, benchmarks) call them.

References
----------
V.V. Lyubimov, E.V. Kurkina, "Optimal control of the angle of attack of an asymmetric
spacecraft in the Mars atmosphere", eqs. (2), (12)-(17).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.params import ParameterError, Params, param

__all__ = ["CONSISTENT", "PAPER", "MarsBellmanParams", "consistent_gain", "paper_gain", "gain",
           "control", "feedback", "bellman_residual", "MarsBellmanController"]

#: ``formula`` values.
CONSISTENT, PAPER = 0, 1


@dataclass(frozen=True)
class MarsBellmanParams(Params):
    """Parameters of the law (17); defaults are our [choice]s (models/README.md).

    The weights are those of the criterion eps * integral(b alpha^2 + c u^2) dt; with eps = 1
    ``u_max`` is an angular acceleration [rad/s^2].
    """

    b: float = param(1.0, "1", "weight of alpha^2 in the criterion (> 0)", positive=True)
    c: float = param(100.0, "1", "weight of u^2 in the criterion (> 0)", positive=True)
    # the plant's default theta1 (MarsParams); this module does not import the plant
    theta1: float = param(0.3, "rad", "phase of the asymmetry (= the plant's theta1)")
    u_max: float = param(0.01, "1", "saturation |u| <= u_max (0: no control)")
    formula: int = param(CONSISTENT, "1", "gain A: 0 consistent root of eq. (14), 1 the "
                         "paper's printed root (15) with its guards")

    def check(self) -> None:
        if self.u_max < 0.0:
            raise ParameterError(f"parameter u_max must be finite and >= 0, got {self.u_max!r}")
        if self.formula not in (CONSISTENT, PAPER):
            raise ParameterError(f"parameter formula must be 0 (consistent root) or 1 (paper's "
                                 f"root), got {self.formula!r}")


def consistent_gain(omega, omega_dot, omega_a, b, c):
    """Positive root A of eq. (14) [same units as c / s].

    Parameters
    ----------
    omega, omega_dot, omega_a : float
        Precession frequency [rad/s], its rate [rad/s^2], omega_a [rad/s] (> 0).
    b, c : float
        Weights of the criterion (> 0).
    """
    x = omega * omega_dot / (omega_a * omega_a)
    y = b / (2.0 * c * omega_a * omega_a)
    root = math.sqrt(x * x + y)
    # -x + root loses digits for x >> sqrt(y); y / (x + root) is the same number
    s = root - x if x <= 0.0 else y / (x + root)
    return 4.0 * c * omega_a * omega_a * s


def paper_gain(omega, omega_dot, omega_a, b, c):
    """The paper's printed root (15), A_1 (the larger), or 0 where its guards (16) fail."""
    if not omega_dot < 0.0:
        return 0.0
    wa2 = omega_a * omega_a
    x = omega * omega_dot / wa2
    d = x * x - b / (4.0 * c * wa2)
    if d < 0.0:
        return 0.0
    return 8.0 * c * wa2 * (-x + math.sqrt(d))


def gain(omega, omega_dot, omega_a, b, c, formula=CONSISTENT):
    """A by ``formula`` (:data:`CONSISTENT` or :data:`PAPER`)."""
    if formula == PAPER:
        return paper_gain(omega, omega_dot, omega_a, b, c)
    return consistent_gain(omega, omega_dot, omega_a, b, c)


def bellman_residual(A, omega, omega_dot, omega_a, b, c):
    """Left side of eq. (14) divided by eps alpha^2: zero for the consistent root."""
    wa2 = omega_a * omega_a
    return b - A * omega * omega_dot / wa2 - A * A / (8.0 * c * wa2)


def control(alpha, theta, omega, omega_dot, omega_a, b, c, theta1, u_max, formula=CONSISTENT):
    """The law (17): returns ``(u, A)``; ``u = 0`` if an input is not finite or omega_a <= 0.

    Parameters
    ----------
    alpha, theta : float
        Spatial angle of attack and fast phase [rad].
    omega, omega_dot, omega_a : float
        [rad/s], [rad/s^2], [rad/s].
    b, c, theta1, u_max : float
        Weights (> 0), asymmetry phase [rad], saturation (>= 0).
    formula : int
        :data:`CONSISTENT` or :data:`PAPER`.
    """
    if not (omega_a > 0.0 and math.isfinite(omega_a) and math.isfinite(omega)
            and math.isfinite(omega_dot) and math.isfinite(alpha) and math.isfinite(theta)):
        return 0.0, 0.0
    A = gain(omega, omega_dot, omega_a, b, c, formula)
    u = A * alpha * math.cos(theta + theta1) / (2.0 * c * omega_a)
    return (u_max if u > u_max else (-u_max if u < -u_max else u)), A


def feedback(law: MarsBellmanParams = MarsBellmanParams(), alpha_index: int = 0):
    """The law as ``control(outputs) -> u`` for :func:`descent_fmus.models.mars.simulate`.

    The plant's output tuple holds ``alpha, theta`` at ``alpha_index, alpha_index + 1`` (0: the
    averaged plant's angles, or the rigid body's instantaneous ones; the index of ``alpha_m1``
    in ``OUTPUTS6``: the rigid body's omega_1 mode) and ``omega, omega_dot, omega_a`` at 2-4.
    """
    b, c, theta1, u_max, formula = law.b, law.c, law.theta1, law.u_max, law.formula
    i = alpha_index

    def u(y):
        return control(y[i], y[i + 1], y[2], y[3], y[4], b, c, theta1, u_max, formula)[0]
    return u


class MarsBellmanController(SlaveBase):
    """Controller FMU of the law (17); outputs are computed from the inputs when read.

    Inputs ``alpha theta omega omega_dot omega_a``; parameters ``b c theta1 u_max`` (Real) and
    ``formula`` (Integer: 0 consistent root, 1 the paper's printed root with its guards);
    outputs ``u`` and ``A``.  A static law has direct feed-through, so a master that reads ``u``
    right after setting the inputs gets u(y(t_k)).
    """

    params_class = MarsBellmanParams

    description = ("S2 Bellman/averaging angle-of-attack law u = A alpha cos(theta+theta1)/"
                   "(2 c omega_a); Lyubimov & Kurkina")

    INPUTS = [("alpha", 0.0, "spatial angle of attack [rad]"),
              ("theta", 0.0, "fast phase [rad]"),
              ("omega", 0.0, "precession frequency [rad/s]"),
              ("omega_dot", 0.0, "rate of omega [rad/s2]"),
              ("omega_a", 1.0, "omega_a = sqrt(Ix_bar^2 omega_x^2/4 + omega^2) [rad/s]")]

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._cache = None
        touch = self._touch
        for name, start, desc in self.INPUTS:
            self.input(name, start, desc,
                       setter=lambda v, n=name: (setattr(self, n, v), touch()))
        self.parameters()
        self.output("u", "control m^A [1]", getter=lambda: self._outputs()[0])
        self.output("A", "Bellman coefficient A of v = A alpha^2 [1]",
                    getter=lambda: self._outputs()[1])
        self.apply_resource_defaults()

    def _touch(self):
        self._cache = None

    def prepare(self) -> None:
        self._cache = None

    def _outputs(self):
        if self._cache is None:
            self._cache = control(self.alpha, self.theta, self.omega, self.omega_dot,
                                  self.omega_a, self.b, self.c, self.theta1, self.u_max,
                                  self.formula)
        return self._cache

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True
