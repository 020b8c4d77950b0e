"""S4 flexible variant -- the telescope carrying two solar panels, two modal coordinates each.

State ``x = (lam[4], w[3], beta[n], eta[4], deta[4])`` (21 with six gyrodynes): the rigid state
of ``models/telescope_dynamics.py`` followed by the modal coordinates ``eta`` [sqrt(kg) m]
(mass-normalised: panel 1 modes 1-2, panel 2 modes 1-2) and their rates.  Hybrid-coordinates
model (Voronov 2009, Example 2, eq. (10)):

    I dw/dt + D^T d2eta/dt2 + w x (I w + k + D^T deta/dt) + dk/dt = 0
    d2eta/dt2 + D dw/dt + 2 zeta Omega deta/dt + Omega^2 eta = 0
    dlam/dt = 1/2 A(w) lam,   dbeta/dt = u

``I`` is the inertia of the whole telescope with undeformed panels (the rigid model's I), ``D``
(4x3) the rotation-elastic coupling [sqrt(kg) m], ``Omega`` the modal frequencies [rad/s],
``zeta`` the damping ratios.  Solved for the accelerations with the constant matrix
``I - D^T D``.  With ``eta = deta = 0`` and ``D = 0`` it is the rigid model.  First integrals:
``|lam| = 1`` and ``K = R(lam) (I w + k + D^T deta)``.

Panel data ([choice], models/README.md): panels along +-y, first out-of-plane bending mode
0.20 Hz coupled with rotation about x (|D| = 40 sqrt(kg) m: effective modal mass ~65 kg at
~5 m; D^T D = 3200 kg m^2 = 13 % of I_xx), first torsion mode 0.60 Hz coupled with rotation
about y (|D| = 5 sqrt(kg) m), damping ratio 0.005 for all modes.  With these values the rigid
solution flown on the flexible model misses by ~8e-5 -- the order of the deviations the thesis
reports (1e-4 ... 1e-5) between its full and reduced models.

The FMU integrates with the rigid model's :class:`~models.telescope.AttitudeIntegrator` (the
right-hand side differs), so it follows the same status convention.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Example 2 (non-rigid telescope).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from pythonfmu import Fmi2Causality

from descent_fmus.models.params import ParameterError, Params, description_of, param
from descent_fmus.models.telescope import Telescope
from descent_fmus.models.telescope_cmg import gyro_sums, quat_to_matrix, quaternion_rate
from descent_fmus.models.telescope_dynamics import TelescopeParams, gyro_momentum
from descent_fmus.models.traceable import minimum

__all__ = ["PanelParams", "make_flexible_rhs", "flexible_inertial_momentum", "FlexibleTelescope",
           "N_MODES", "flexible_initial_state"]

#: Modal coordinates: two panels x two modes.
N_MODES = 4


@dataclass(frozen=True)
class PanelParams(Params):
    """Solar-panel modes ([choice]; see the module docstring and models/README.md).

    :meth:`validate` with the body's :class:`~models.telescope_dynamics.TelescopeParams` also
    checks that the panels do not outweigh the body (``I - D^T D`` positive definite).
    """

    coupling: tuple = param((40.0, 0.0, 0.0,
                             0.0, 5.0, 0.0,
                             -40.0, 0.0, 0.0,
                             0.0, 5.0, 0.0), "sqrt(kg).m",
                            "rotation-elastic coupling D, row-major 4 modes x 3 axes")
    freq: tuple = param((0.20, 0.60, 0.20, 0.60), "Hz", "modal frequencies")
    zeta: tuple = param((0.005, 0.005, 0.005, 0.005), "1", "modal damping ratios")

    @property
    def D(self) -> np.ndarray:
        return np.array(self.coupling, float).reshape(N_MODES, 3)

    def check(self) -> None:
        if len(self.coupling) != 3 * N_MODES or len(self.freq) != N_MODES \
                or len(self.zeta) != N_MODES:
            raise ParameterError(f"panel data need 12 couplings, {N_MODES} frequencies and "
                                 f"{N_MODES} damping ratios")
        if minimum(*self.freq) <= 0.0 or minimum(*self.zeta) < 0.0:
            raise ParameterError("modal frequencies must be > 0 [Hz] and damping ratios >= 0")

    def validate(self, body: TelescopeParams | None = None) -> "PanelParams":
        """:meth:`Params.validate`, then (given the ``body``) the coupling against its inertia."""
        super().validate()
        if body is not None:
            ev = np.linalg.eigvalsh(body.I - self.D.T @ self.D)
            if ev[0] <= 0.0:
                raise ParameterError("coupling too strong: I - D^T D must be positive definite "
                                     f"(eigenvalues {ev}) -- the panels cannot outweigh the body")
        return self


def make_flexible_rhs(p: TelescopeParams, pp: PanelParams):
    """Return ``f(x, u)`` of the flexible telescope on tuples (15 + n states, n controls)."""
    p.validate()
    pp.validate(p)
    I = p.I
    D = pp.D
    Ic_inv = np.linalg.inv(I - D.T @ D)
    i11, i12, i13, i21, i22, i23, i31, i32, i33 = p.inertia
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = (float(v) for v in Ic_inv.ravel())
    Dl = [tuple(float(v) for v in r) for r in D]
    om = [2.0 * math.pi * f for f in pp.freq]
    damp = [2.0 * z * o for z, o in zip(pp.zeta, om)]
    stiff = [o * o for o in om]
    ha, hb = p.gyro_matrices()
    gy = [(tuple(float(v) for v in a), tuple(float(v) for v in b)) for a, b in zip(ha, hb)]
    modes = list(zip(Dl, damp, stiff))
    n = len(gy)
    e0, d0 = 7 + n, 7 + n + N_MODES          # first modal coordinate and rate

    def rhs(x, u):
        l0, l1, l2, l3, w1, w2, w3 = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
        k1, k2, k3, d1, d2, d3 = gyro_sums(x, u, gy)
        # modal momentum D^T deta and modal forces r2 = -2 zeta Omega deta - Omega^2 eta
        p1 = p2 = p3 = 0.0
        s1 = s2 = s3 = 0.0
        r2 = []
        i = 0
        for (dv, dd, kk) in modes:
            e, de = x[e0 + i], x[d0 + i]
            p1 += dv[0] * de
            p2 += dv[1] * de
            p3 += dv[2] * de
            f = -dd * de - kk * e
            r2.append(f)
            s1 += dv[0] * f
            s2 += dv[1] * f
            s3 += dv[2] * f
            i += 1
        L1 = i11 * w1 + i12 * w2 + i13 * w3 + k1 + p1
        L2 = i21 * w1 + i22 * w2 + i23 * w3 + k2 + p2
        L3 = i31 * w1 + i32 * w2 + i33 * w3 + k3 + p3
        r1 = -(w2 * L3 - w3 * L2) - d1 - s1
        r2_ = -(w3 * L1 - w1 * L3) - d2 - s2
        r3 = -(w1 * L2 - w2 * L1) - d3 - s3
        a1 = c11 * r1 + c12 * r2_ + c13 * r3
        a2 = c21 * r1 + c22 * r2_ + c23 * r3
        a3 = c31 * r1 + c32 * r2_ + c33 * r3
        eta_dd = tuple(f - (dv[0] * a1 + dv[1] * a2 + dv[2] * a3)
                       for f, (dv, _, _) in zip(r2, modes))
        return (quaternion_rate(l0, l1, l2, l3, w1, w2, w3) + (a1, a2, a3) + tuple(u[:n])
                + tuple(x[d0:d0 + N_MODES]) + eta_dd)
    return rhs


def flexible_initial_state(rigid_x0) -> tuple:
    """The rigid initial state with the panels undeformed and at rest."""
    return tuple(rigid_x0) + (0.0,) * (2 * N_MODES)


def flexible_inertial_momentum(x, p: TelescopeParams, pp: PanelParams) -> np.ndarray:
    """First integral K = R(lam) (I w + k + D^T deta) [N m s]."""
    x = np.asarray(x, float)
    n = p.n_gyros
    body = (p.I @ x[4:7] + gyro_momentum(x[7:7 + n], p)
            + pp.D.T @ x[7 + n + N_MODES:7 + n + 2 * N_MODES])
    return quat_to_matrix(x) @ body


class FlexibleTelescope(Telescope):
    """FMU of the flexible S4 telescope (two panels x two modes); interface of :class:`Telescope`
    plus the modal coordinates ``eta1..eta4`` and the panel parameters."""

    description = ("S4 orbital telescope with two flexible solar panels (2 modes each), six "
                   "gyrodynes; Voronov 2009, Example 2")

    def _register_extra_parameters(self):
        d = PanelParams()
        for f in fields(PanelParams):
            values = list(getattr(d, f.name))
            setattr(self, f.name, values)
            self.real_array(f.name, values, Fmi2Causality.parameter,
                            description_of(PanelParams, f.name))

    def _register_extra_outputs(self):
        for k in range(N_MODES):
            self.output(f"eta{k + 1}", f"modal coordinate {k + 1} (panel {k // 2 + 1}, mode "
                        f"{k % 2 + 1}) [sqrt(kg) m]",
                        getter=lambda k=k: self._ig.x[7 + self._n + k])

    def _panel_params(self) -> PanelParams:
        return PanelParams(**{f.name: tuple(getattr(self, f.name)) for f in fields(PanelParams)})

    def _momentum(self):
        return flexible_inertial_momentum(self._ig.x, self._params, self._panels)

    def _initial_state(self):
        return flexible_initial_state(super()._initial_state())

    def _make_rhs(self):
        return make_flexible_rhs(self._params, self._panels)

    def check_parameters(self) -> None:
        super().check_parameters()
        self._panel_params().validate(self.params())

    def prepare(self) -> None:
        self._panels = self._panel_params()
        super().prepare()
