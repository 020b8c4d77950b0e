"""S2 check of the averaging: the capsule's full rigid-body rotation (Euler's equations).

The same descent and aerodynamics as :mod:`descent_fmus.models.mars` (functions
:func:`descent` and :func:`precession` are shared), but instead of the averaged (alpha, theta)
equations the body rates ``(wx, wy, wz)`` and the direction of the velocity in body axes
``v = (vx, vy, vz)`` (a unit vector, x = symmetry axis) are integrated::

    dv/dt = v x w                                   (velocity direction fixed in inertial space)
    Ix dwx/dt = 0                                   (no axial moment: wx = omega_x)
    I dwy/dt  = My - (Ix - I) wx wz
    I dwz/dt  = Mz + (I - Ix) wx wy
    M / I = omega^2 (e_x x v)  +  eps u (0, -sin theta1, cos theta1)

The first moment is the restoring moment ``-mz_alpha q S L sin(alpha)`` (omega^2 = -mz_alpha q S L
/ I as in the averaged model), the second the body-fixed asymmetry moment of the control.
Outputs: the spatial angle of attack ``alpha = atan2(sqrt(vy^2 + vz^2), vx)`` and the fast phase
``theta = -atan2(vz, vy) - pi/2`` (aerodynamic roll angle minus pi/2, wrapped to (-pi, pi]).

With this convention the linearised equations, written for the complex angle of attack and
split into the two precession modes omega_{1,2} = Ix_bar wx / 2 +- omega_a, give exactly the
averaged equations of :mod:`descent_fmus.models.mars` for the amplitude of the omega_1 mode
(variation of constants; models/README.md).  The initial state is a pure omega_1 coning motion with
amplitude ``alpha0`` and phase ``theta0`` -- the motion the averaged model describes.

The rotation of the velocity vector by gravity (d gamma / dt) is neglected, as in the averaged
model: both plants see the same moments, so their difference is the averaging alone.

References
----------
V.V. Lyubimov, E.V. Kurkina, "Optimal control of the angle of attack of an asymmetric
spacecraft in the Mars atmosphere", eq. (1), and its source, Yu.M. Zabolotnov, Kosmicheskie
Issledovaniya 32(3), 1994 (quasi-linear equations of a capsule with small asymmetry).
"""
from __future__ import annotations

import math

from descent_fmus.models.mars import (MarsCapsule, MarsIntegrator, MarsParams, descent,
                                     precession)
from descent_fmus.models.traceable import minimum, where

__all__ = ["rhs6", "observe6", "initial_state6", "Mars6DOFIntegrator", "MarsCapsule6DOF",
           "OUTPUTS6", "DT_6DOF"]

#: Default RK4 sub-step of the rigid-body plant [s]: the fastest body-axis motion (the omega_2
#: mode, seen at wx - omega_2 ~ 5.3 rad/s) is resolved with ~60 steps per period.
DT_6DOF = 0.02
_HALF_PI = 0.5 * math.pi


def rhs6(x, u, kd, kw, ix_bar, g0, R, rho0, inv_hs, omega_x, theta1, eps):
    """Right-hand side, state ``(V, gamma, h, s, vx, vy, vz, wx, wy, wz)`` (SI units, rad/s).

    Same arguments as :func:`descent_fmus.models.mars.rhs`.
    """
    V, gamma, h, _, vx, vy, vz, wx, wy, wz = x
    dV, dg, dh, ds, q, _ = descent(V, gamma, h, kd, g0, R, rho0, inv_hs)
    w2 = kw * q
    eu = eps * u
    k = 1.0 - ix_bar
    return (dV, dg, dh, ds,
            vy * wz - vz * wy, vz * wx - vx * wz, vx * wy - vy * wx,
            0.0,
            -w2 * vz - eu * math.sin(theta1) + k * wx * wz,
            w2 * vy + eu * math.cos(theta1) - k * wx * wy)


def observe6(x, args):
    """Outputs :data:`OUTPUTS6`: the averaged plant's ``OUTPUTS``, the body rates ``wx, wy, wz``
    and the precession modes ``alpha_m1, theta_m1, alpha_m2``."""
    kd, kw, ix_bar, g0, R, rho0, inv_hs, omega_x, _, _ = args
    V, gamma, h, s, vx, vy, vz, wx, wy, wz = x
    _, _, _, _, q, dq = descent(V, gamma, h, kd, g0, R, rho0, inv_hs)
    w, wd, wa = precession(q, dq, kw, ix_bar, omega_x)
    alpha = math.atan2(math.hypot(vy, vz), vx)
    theta = _phase(vy, vz)
    # precession modes: with w = vy + i vz and W = vx (wy + i wz), w = m1 + m2 where m1, m2
    # rotate at omega_1 - wx, omega_2 - wx:  m1 = (W - omega_2 w) / (2 omega_a), m2 = w - m1
    half = 0.5 * ix_bar * wx
    w2r = half - wa
    m1y = (vx * wy - w2r * vy) / (2.0 * wa)
    m1z = (vx * wz - w2r * vz) / (2.0 * wa)
    a1 = math.asin(minimum(1.0, math.hypot(m1y, m1z)))
    a2 = math.asin(minimum(1.0, math.hypot(vy - m1y, vz - m1z)))
    return (alpha, theta, w, wd, wa, q, dq, omega_x - 0.5 * ix_bar * omega_x - wa, h, V, gamma,
            s, wx, wy, wz, a1, _phase(m1y, m1z), a2)


def _phase(y, z):
    """theta of a body-axis direction (y, z): -atan2(z, y) - pi/2 wrapped to (-pi, pi]."""
    theta = -math.atan2(z, y) - _HALF_PI
    return where(theta <= -math.pi, lambda: theta + 2.0 * math.pi, theta)


#: Names of :func:`observe6`'s values (the FMU's Real outputs besides t_end).
OUTPUTS6 = ("alpha", "theta", "omega", "omega_dot", "omega_a", "q", "q_dot", "theta_dot", "h",
            "V", "gamma", "s", "wx", "wy", "wz", "alpha_m1", "theta_m1", "alpha_m2")


def initial_state6(p: MarsParams) -> tuple:
    """Pure omega_1 coning with amplitude alpha0 and phase theta0 (steady for frozen q).

    For ``w = vy + i vz`` rotating at ``omega_1 - wx`` the Euler equations hold exactly with
    ``(wy, wz) = omega_1 (vy, vz) / vx`` and ``omega_1^2 - Ix_bar wx omega_1 - omega^2 vx = 0``.
    """
    kd, kw, ix_bar, g0, R, rho0, inv_hs, omega_x, _, _ = p.constants()
    _, _, _, _, q, _ = descent(p.V0, p.gamma0, p.h0, kd, g0, R, rho0, inv_hs)
    ca, sa = math.cos(p.alpha0), math.sin(p.alpha0)
    psi = -p.theta0 - _HALF_PI
    vy, vz = sa * math.cos(psi), sa * math.sin(psi)
    half = 0.5 * ix_bar * omega_x
    w1 = half + math.sqrt(half * half + kw * q * ca)
    return (p.V0, p.gamma0, p.h0, 0.0, ca, vy, vz, omega_x, w1 * vy / ca, w1 * vz / ca)


class Mars6DOFIntegrator(MarsIntegrator):
    """The integrator of the rigid-body plant: :class:`MarsIntegrator` with :func:`rhs6`,
    :func:`initial_state6` and the outputs :data:`OUTPUTS6`."""

    f = staticmethod(rhs6)
    observe = staticmethod(observe6)
    names = OUTPUTS6

    def __init__(self, p: MarsParams, dt: float = DT_6DOF):
        super().__init__(p, dt)

    def initial_state(self) -> tuple:
        return initial_state6(self.p)


class MarsCapsule6DOF(MarsCapsule):
    """FMU of the rigid-body S2 plant: same parameters, input and outputs as MarsCapsule, plus
    the body rates ``wx wy wz`` and the precession modes; ``alpha`` and ``theta`` are the
    instantaneous angles."""

    integrator = Mars6DOFIntegrator
    DT = DT_6DOF

    description = ("S2 asymmetric capsule in the Mars atmosphere: point-mass descent + rigid-body "
                   "rotation (Euler's equations); check of the averaging of Lyubimov & Kurkina")

    OUTPUT_DESCRIPTIONS = dict(
        MarsCapsule.OUTPUT_DESCRIPTIONS,
        wx="body rate about the symmetry axis [rad/s]",
        wy="body rate about y [rad/s]", wz="body rate about z [rad/s]",
        alpha_m1="amplitude of the omega_1 precession mode (the averaged alpha) [rad]",
        theta_m1="phase theta of the omega_1 precession mode [rad]",
        alpha_m2="amplitude of the omega_2 precession mode [rad]")
