"""S4 reorientation of the orbital telescope by the direct method (rigid and flexible models).

* :func:`reorient` -- checks that the target is inside the CMG momentum envelope (and, with a
  gimbal-rate limit, that the limit can move the rotors far enough), then solves the
  reorientation with :func:`synthesis.methods.direct_method.solve` (rigid model; or the
  flexible model with the *reduced* algorithm: linearise the rigid model, close the miss on the
  flexible one); optionally with the gimbal-rate limits ``|u_j| <= u_max`` and/or for the
  minimum-energy control (least ``int |u|^2 dt``);
* :func:`path_metrics` -- invariant drift, singularity measure along the path;
* :func:`replay` -- fly the computed program through the FMUs with fmpy (ProgramController +
  Telescope / FlexibleTelescope) and compare with the target;
* :func:`plot_reorientation` -- one PNG of u(t), w(t), lam(t), beta(t), the singularity measure
  (the modal coordinates) and the miss per iteration;
* :func:`write_programs` -- store the default programs that the closed-loop FMUs carry
  (``programs.json``, :mod:`synthesis.systems.telescope.wiring`).

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Examples 1-2.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from descent_fmus.models.telescope import DT_INTEGRATION
from descent_fmus.models.telescope_dynamics import (INITIAL_STATE, T_DEFAULT, TARGET_LAM, TARGET_W,
                                                    TelescopeParams, envelope_radius, gyro_momentum,
                                                    inertial_momentum, make_rigid_rhs,
                                                    required_gyro_momentum, rigid_jacobian,
                                                    singularity_measure)
from descent_fmus.models.telescope_flexible import (PanelParams, flexible_inertial_momentum,
                                                    flexible_initial_state, make_flexible_rhs)
from descent_fmus.synthesis.methods.direct_method import (BoundaryProblem, DirectResult,
                                                          LinearModel, simulate, solve)

__all__ = ["UnreachableTargetError", "RateLimitTooSmallError", "Reorientation", "reorient",
           "check_reachable", "check_rate_limit", "U_MAX_DEFAULT", "ENERGY_REFERENCE",
           "ENERGY_TARGET",
           "path_metrics", "replay", "plot_reorientation", "rigid_problem", "flexible_problem",
           "write_programs", "GRID_STEP", "TOL_RIGID", "TOL_FLEXIBLE", "MAX_ITER",
           "PAPER_SECONDS", "PAPER_ITERATIONS", "STATE_NAMES"]

#: Control grid spacing [s] ([choice]: 40 intervals over the 40 s of the reorientation).
GRID_STEP = 1.0
#: The components of the end conditions (quaternion and body rate).
STATE_NAMES = ("lam0", "lam1", "lam2", "lam3", "w1", "w2", "w3")
#: Default tolerances on every end condition: rigid model (Voronov 2009, Example 1) and flexible
#: model with the reduced algorithm (Example 2).
TOL_RIGID, TOL_FLEXIBLE = 1e-7, 1e-8
#: Default iteration limit of the direct method.
MAX_ITER = 20
#: The thesis' figures for the rigid case (Voronov 2009, Example 1).
PAPER_SECONDS = 1.7
PAPER_ITERATIONS = 5
#: Default gimbal-rate limit [rad/s] of ``--u-max`` ([choice]: binds for Example 1, whose
#: unconstrained peak is 0.137 rad/s).
U_MAX_DEFAULT = 0.1
#: Least ``int |u|^2 dt`` [rad^2/s] found for Example 1 by CasADi + IPOPT (piecewise-linear u,
#: 40 intervals), the reference of the minimum-energy option; accepted within 5 %.
ENERGY_REFERENCE = 0.251
ENERGY_TARGET = 1.05 * ENERGY_REFERENCE


class UnreachableTargetError(ValueError):
    """The end state needs a gyro momentum outside the CMG envelope (no control can reach it)."""


class RateLimitTooSmallError(ValueError):
    """The gimbal-rate limit cannot turn the rotors far enough in the time given."""


def check_reachable(x0, lam_f, w_f, p: TelescopeParams, margin: float = 1.0) -> dict:
    """Raise :class:`UnreachableTargetError` if the target needs |k| beyond the envelope.

    The inertial momentum K is conserved, so at T the gyros must hold
    ``k_f = R(lam_f)^T K - I w_f``; along its direction e the n gyros reach at most
    ``h sum_j sqrt(1 - (e.g_j)^2)`` (:func:`models.telescope_dynamics.envelope_radius`).
    Checked before iterating, so an impossible target is a message, not a diverging loop.
    """
    nrm = float(np.linalg.norm(lam_f))
    if not math.isfinite(nrm) or abs(nrm - 1.0) > 1e-9:
        raise UnreachableTargetError(f"target quaternion must have unit norm, |lam_f| = {nrm}")
    kf = required_gyro_momentum(x0, lam_f, w_f, p)
    need = float(np.linalg.norm(kf))
    n = p.n_gyros
    limit = envelope_radius(kf, p) if need > 0 else n * p.h
    if need >= margin * limit:
        raise UnreachableTargetError(
            f"the target needs a gyro angular momentum of {need:.1f} N m s along "
            f"({kf[0] / need:+.3f}, {kf[1] / need:+.3f}, {kf[2] / need:+.3f}) but the {n} "
            f"gyros reach at most {limit:.1f} N m s in that direction ({n}h = {n * p.h:.0f}): "
            "lower the final body rate or change the target attitude")
    return dict(k_required=need, envelope=limit, fraction=need / limit)


def check_rate_limit(x0, lam_f, w_f, p: TelescopeParams, u_max: float, T: float) -> dict:
    """Raise :class:`RateLimitTooSmallError` if ``|u_j| <= u_max`` cannot change the gyro
    momentum from ``k(beta0)`` to the ``k_f`` the target needs within ``T``.

    A necessary condition in closed form: gimbal j turns at most ``u_max T`` (and at most pi
    matters), moving its rotor momentum by at most the chord ``2 h sin(min(u_max T, pi) / 2)``,
    so ``|k_f - k(beta0)| <= n 2 h sin(min(u_max T, pi) / 2)``.  A limit that passes may still
    be too small (the path matters): the direct method then stops with a message after a
    bounded number of iterations.
    """
    n = p.n_gyros
    dk = float(np.linalg.norm(required_gyro_momentum(x0, lam_f, w_f, p)
                              - gyro_momentum(np.asarray(x0, float)[7:7 + n], p)))
    reach = 2.0 * n * p.h * math.sin(min(u_max * T, math.pi) / 2.0)
    if dk > reach:
        need = 2.0 * math.asin(min(1.0, dk / (2.0 * n * p.h))) / T
        raise RateLimitTooSmallError(
            f"the gimbal-rate limit {u_max:g} rad/s is too small: in {T:g} s it turns every "
            f"rotor by at most {u_max * T:.3g} rad, moving the gyro momentum by at most "
            f"{reach:.1f} N m s, but the target needs a change of {dk:.1f} N m s (any limit "
            f"below {need:.3g} rad/s cannot reach it)")
    return dict(dk_required=dk, dk_reachable=reach)


def rigid_problem(p: TelescopeParams, T: float, lam_f, w_f, x0=INITIAL_STATE,
                  grid_step: float = GRID_STEP, dt: float = DT_INTEGRATION) -> BoundaryProblem:
    """The boundary problem of the rigid reorientation: from ``x0`` to (``lam_f``, ``w_f``).

    Parameters
    ----------
    p : TelescopeParams
    T : float
        Reorientation time [s].
    lam_f, w_f : sequence
        Target quaternion [1] and body rate [rad/s].
    x0 : sequence
        Initial state (7 + n).
    grid_step : float
        Control grid spacing [s] (rounded to a whole number of intervals over T).
    dt : float
        Largest RK4 sub-step [s] (an even number of sub-steps per interval).
    """
    n = max(2, int(round(T / grid_step)))
    m = max(2, 2 * int(math.ceil(T / n / dt / 2 - 1e-9)))
    return BoundaryProblem(rhs=make_rigid_rhs(p), x0=tuple(x0), tf=T,
                           target_index=tuple(range(7)), target_value=tuple(lam_f) + tuple(w_f),
                           n_u=p.n_gyros, intervals=n, substeps=m, jac=rigid_jacobian(p))


def flexible_problem(p: TelescopeParams, pp: PanelParams, T: float, lam_f, w_f,
                     x0=INITIAL_STATE, grid_step: float = GRID_STEP,
                     dt: float = DT_INTEGRATION) -> BoundaryProblem:
    """The boundary problem of the flexible reorientation (panels ``pp`` undeformed at rest at
    t = 0; the same grid and end conditions as :func:`rigid_problem`, no analytic Jacobian)."""
    rp = rigid_problem(p, T, lam_f, w_f, x0, grid_step, dt)
    return BoundaryProblem(rhs=make_flexible_rhs(p, pp), x0=flexible_initial_state(x0), tf=T,
                           target_index=rp.target_index, target_value=rp.target_value,
                           n_u=p.n_gyros,
                           intervals=rp.intervals, substeps=rp.substeps)


@dataclass
class Reorientation:
    """A solved S4 reorientation: the direct-method result plus path metrics.

    ``rigid_on_flexible_miss`` (flexible case only): max end error of the rigid model's
    solution flown on the flexible model -- why the reduced algorithm is needed.
    """

    flexible: bool
    T: float
    tol: float
    result: DirectResult
    metrics: dict
    reach: dict
    params: TelescopeParams
    panels: PanelParams | None = None
    rigid_on_flexible_miss: float | None = None
    warm_iterations: int | None = None
    extra: dict = field(default_factory=dict)
    min_energy: bool = False

    def summary(self) -> dict:
        r = self.result
        s = dict(model="flexible" if self.flexible else "rigid", T=self.T, tol=self.tol,
                 success=r.success, iterations=r.iterations,
                 miss_per_iteration=[h["max_miss"] for h in r.history],
                 selected_per_iteration=[h["selected"] for h in r.history[1:]],
                 seconds=r.seconds, paper_seconds=PAPER_SECONDS,
                 paper_iterations=PAPER_ITERATIONS,
                 final_errors=dict(zip(STATE_NAMES, map(float, r.miss))),
                 u_start=[float(v) for v in r.controls[0]],
                 u_end=[float(v) for v in r.controls[-1]],
                 u_max_abs=float(np.max(np.abs(r.controls))),
                 u_max=None if r.u_max is None else float(np.max(r.u_max)),
                 min_energy=self.min_energy, energy=r.energy,
                 k_required=self.reach["k_required"], envelope=self.reach["envelope"])
        s.update(self.metrics)
        if self.flexible:
            s["rigid_solution_on_flexible_miss"] = self.rigid_on_flexible_miss
            s["iterations_from_rigid_solution"] = self.warm_iterations
        s.update(self.extra)
        return s


def path_metrics(res: DirectResult, p: TelescopeParams, pp: PanelParams | None = None) -> dict:
    """|lam| and inertial-momentum drift, singularity measure along the solution's sub-steps."""
    X = res.states
    lam_dev = float(np.max(np.abs(np.linalg.norm(X[:, :4], axis=1) - 1.0)))
    if pp is None:
        K = np.array([inertial_momentum(x, p) for x in X])
    else:
        K = np.array([flexible_inertial_momentum(x, p, pp) for x in X])
    dK = float(np.max(np.linalg.norm(K - K[0], axis=1)))
    n = p.n_gyros
    sing = np.array([singularity_measure(x[7:7 + n], p) for x in X])
    i = int(np.argmin(sing))
    out = dict(lam_norm_drift=lam_dev, momentum_drift=dK,
               momentum_drift_relative=dK / float(np.linalg.norm(K[0])),
               K0=[float(v) for v in K[0]], sing_min=float(sing[i]), sing_min_time=float(res.t[i]),
               sing_start=float(sing[0]), sing_end=float(sing[-1]), sing_max_possible=8.0)
    if pp is not None:
        out["eta_max"] = float(np.max(np.abs(X[:, 7 + n:11 + n])))
    return out


def reorient(flexible: bool = False, T: float = T_DEFAULT, tol: float | None = None,
             lam_f=TARGET_LAM, w_f=TARGET_W, params: TelescopeParams = TelescopeParams(),
             panels: PanelParams = PanelParams(), max_iter: int = MAX_ITER,
             grid_step: float = GRID_STEP, u_max: float | None = None,
             min_energy: bool = False, x0=INITIAL_STATE) -> Reorientation:
    """Solve the S4 reorientation (Voronov 2009, Examples 1-2) by the direct method.

    Parameters
    ----------
    flexible : bool
        Flexible telescope with the reduced algorithm (default tolerance ``TOL_FLEXIBLE``)
        instead of the rigid one (default ``TOL_RIGID``).
    T : float
        Reorientation time [s].
    tol : float, optional
        Tolerance on every component of lam [1] and w [rad/s].
    lam_f, w_f : sequence
        Target quaternion and body rate [rad/s].
    params, panels : TelescopeParams, PanelParams
        The body and (flexible model) the panels.
    max_iter : int
        Iteration limit of the direct method.
    grid_step : float
        Control grid spacing [s].
    u_max : float, optional
        Gimbal-rate limit ``|u_j(t)| <= u_max`` [rad/s] for every gyrodyne and every t.
    min_energy : bool
        Seek the control of least ``int |u|^2 dt`` among those meeting the end conditions.
    x0 : sequence
        Initial state (default: Example 1's).

    Raises
    ------
    models.params.ParameterError
        Invalid ``params`` or ``panels``.
    UnreachableTargetError
        The end state is outside the CMG momentum envelope (checked before iterating).
    RateLimitTooSmallError
        ``u_max`` cannot move the rotors far enough in ``T`` (closed form, before iterating).
    synthesis.methods.direct_method.ConvergenceError
        The iterations failed (the message says why).
    """
    tol, lam_f, w_f, x0, reach = _checked_arguments(flexible, T, tol, lam_f, w_f, params,
                                                    panels, u_max, x0)
    options = dict(u_max=u_max, minimize_energy=bool(min_energy))

    def rigid():
        return replace(rigid_problem(params, T, lam_f, w_f, x0=x0, grid_step=grid_step),
                       **options)

    if not flexible:
        res = solve(rigid(), tol=tol, max_iter=max_iter)
        return Reorientation(False, T, tol, res, path_metrics(res, params), reach, params,
                             min_energy=bool(min_energy))
    pbf = replace(flexible_problem(params, panels, T, lam_f, w_f, x0=x0, grid_step=grid_step),
                  **options)
    res, warm = _solve_flexible(pbf, rigid, params, tol, max_iter)
    return Reorientation(True, T, tol, res, path_metrics(res, params, panels), reach, params,
                         panels, **warm, min_energy=bool(min_energy))


def _checked_arguments(flexible: bool, T: float, tol, lam_f, w_f, params: TelescopeParams,
                       panels: PanelParams, u_max: float | None, x0) -> tuple:
    """Check the arguments of :func:`reorient` before iterating; returns ``(tol, lam_f, w_f,
    x0, reach)``: the tolerance (its default if None), the target and the initial state as
    tuples of floats, and what :func:`check_reachable` (and, with ``u_max``,
    :func:`check_rate_limit`) found.

    Raises
    ------
    ValueError
        A non-positive ``T``, ``tol`` or ``u_max``, or an ``x0`` of the wrong size.
    models.params.ParameterError, UnreachableTargetError, RateLimitTooSmallError
        See :func:`reorient`.
    """
    if not (math.isfinite(T) and T > 0):
        raise ValueError(f"T must be > 0 [s], got {T}")
    tol = (TOL_FLEXIBLE if flexible else TOL_RIGID) if tol is None else float(tol)
    if not tol > 0:
        raise ValueError(f"tol must be > 0, got {tol}")
    lam_f = tuple(float(v) for v in lam_f)
    w_f = tuple(float(v) for v in w_f)
    params.validate()
    if flexible:
        panels.validate(params)
    x0 = tuple(float(v) for v in x0)
    if len(x0) != params.n_states:
        raise ValueError(f"x0 needs {params.n_states} values (lam, w, beta), got {len(x0)}")
    reach = check_reachable(x0, lam_f, w_f, params)
    if u_max is not None:
        if not (math.isfinite(u_max) and u_max > 0):
            raise ValueError(f"u_max must be > 0 [rad/s], got {u_max}")
        reach.update(check_rate_limit(x0, lam_f, w_f, params, u_max, T))
    return tol, lam_f, w_f, x0, reach


def _solve_flexible(pbf: BoundaryProblem, rigid, params: TelescopeParams, tol: float,
                    max_iter: int) -> tuple:
    """Solve the flexible problem ``pbf`` by the reduced algorithm (the rigid model linearised,
    the miss closed on the flexible one), from zero and from the rigid solution.

    ``rigid()`` builds the rigid problem.  The rigid solution flown on the flexible model shows
    why the reduced algorithm is needed; started from it, the reduced algorithm shows what a
    warm start saves.  Returns the result from zero and the :class:`Reorientation` fields of
    the comparison (``rigid_on_flexible_miss``, ``warm_iterations``, ``extra``).
    """
    nr = params.n_states
    reduced = LinearModel(rigid_jacobian(params), project=lambda X: X[:, :nr])
    res = solve(pbf, tol=tol, max_iter=max_iter, linear=reduced)
    t0 = time.perf_counter()
    rig = solve(rigid(), tol=min(tol, 1e-9), max_iter=max_iter)
    _, Xf, _ = simulate(pbf.rhs, pbf.x0, rig.t_nodes, rig.controls, pbf.substeps)
    rof = float(np.max(np.abs(Xf[-1, :7] - np.array(pbf.target_value))))
    warm = solve(pbf, controls=rig.controls, tol=tol, max_iter=max_iter, linear=reduced)
    return res, dict(rigid_on_flexible_miss=rof, warm_iterations=warm.iterations,
                     extra=dict(rigid_then_reduced_seconds=time.perf_counter() - t0))


def replay(ro: Reorientation, fmu_dir=None, step: float | None = None) -> dict:
    """Fly ``ro``'s program through the FMUs with fmpy; end errors vs the target and the solver.

    Uses ``ProgramController.fmu`` with the program as start values and ``Telescope.fmu`` or
    ``FlexibleTelescope.fmu`` (first-order hold through the ``du`` inputs) with ``ro``'s
    parameters, from ``fmu_dir`` (default: :func:`synthesis.paths.fmu_dir`).
    """
    from descent_fmus.models.controllers.program_table import program_values
    from descent_fmus.synthesis.fmi.loop import open_loop
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    from descent_fmus.synthesis.systems.telescope.wiring import PLANTS, plant_values, wiring

    fmu_dir = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    plant = PLANTS["flexible" if ro.flexible else "rigid"]
    r = ro.result
    names = list(STATE_NAMES)
    h = float(r.t_nodes[1] - r.t_nodes[0])
    step = step or h / 2.0
    with open_loop(wiring(plant), fmu_dir / f"{plant}.fmu", fmu_dir / "ProgramController.fmu",
                   native=False, record=names + ["sing"]) as cl:
        t0 = time.perf_counter()
        out = cl.run(plant_values=plant_values(ro.params, ro.panels, dt=float(r.t[1] - r.t[0])),
                     controller_values=program_values(ro.T, r.controls), stop_time=ro.T,
                     step=step, record=True)
        secs = time.perf_counter() - t0
    final = np.array([out.final[n] for n in names])
    target = np.array(r.states[-1, :7]) - np.array(r.miss)
    return dict(replay_error_vs_target=float(np.max(np.abs(final - target))),
                replay_error_vs_solver=float(np.max(np.abs(final - r.states[-1, :7]))),
                replay_sing_min=float(np.min(out["sing"])), replay_seconds=secs,
                replay_step=step, replay_status=out.final["status"],
                final={n: float(v) for n, v in zip(names, final)})


def plot_reorientation(ro: Reorientation, path) -> Path:
    """Write one PNG: the controls, rates, quaternion, gimbal angles, singularity measure (and
    modal coordinates) against time, and the miss per iteration; returns the path."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure

    r, p = ro.result, ro.params
    tag = "flexible" if ro.flexible else "rigid"
    X, t = r.states, r.t
    n = p.n_gyros
    sing = [singularity_measure(x[7:7 + n], p) for x in X]
    rows = 7 if ro.flexible else 6
    fig, ax = plt.subplots(rows, 1, figsize=(8, 2.2 * rows),
                           gridspec_kw={"height_ratios": [1] * (rows - 1) + [1.2]})
    for a in ax[1:-1]:
        a.sharex(ax[0])
    for j in range(n):
        ax[0].plot(r.t_nodes, np.degrees(r.controls[:, j]), label=f"u{j + 1}")
    ax[0].set_ylabel("gimbal rate u [deg/s]")
    for j in range(3):
        ax[1].plot(t, np.degrees(X[:, 4 + j]), label=f"w{j + 1}")
    ax[1].set_ylabel("body rate [deg/s]")
    for j in range(4):
        ax[2].plot(t, X[:, j], label=f"lam{j}")
    ax[2].set_ylabel("quaternion [1]")
    for j in range(n):
        ax[3].plot(t, np.degrees(X[:, 7 + j]), label=f"beta{j + 1}")
    ax[3].set_ylabel("gimbal angle [deg]")
    ax[4].plot(t, sing, "k")
    ax[4].set_ylabel("det(CC^T)/h^6 [1]")
    if ro.flexible:
        for j in range(4):
            ax[5].plot(t, X[:, 7 + n + j], label=f"eta{j + 1}")
        ax[5].set_ylabel("modal coord. [sqrt(kg) m]")
    for a in ax[:-2]:
        a.tick_params(labelbottom=False)
    ax[-2].set_xlabel("t [s]")
    miss = ax[-1]
    miss.semilogy([h["iteration"] for h in r.history], [max(h["max_miss"], 1e-17)
                                                         for h in r.history], "o-")
    miss.axhline(ro.tol, color="r", ls="--", label=f"tol {ro.tol:g}")
    miss.set_xlabel("iteration")
    miss.set_ylabel("max |x_i(T) - x_i,f|")
    for a in ax:
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=7, ncol=6, loc="best")
    fig.suptitle(f"S4 reorientation ({tag}), direct method: {r.iterations} iterations, "
                 f"miss {r.max_miss:.1e}")
    return save_figure(fig, path, axes=ax, dpi=90)


def write_programs(path=None) -> dict:
    """Solve the rigid and the flexible reorientation (defaults) and store their programs as the
    ProgramController start values of the closed loops; returns them.

    ``path`` defaults to :data:`synthesis.systems.telescope.wiring.PROGRAMS_FILE`.
    """
    import json

    from descent_fmus.models.controllers.program_table import program_values
    from descent_fmus.synthesis.systems.telescope.wiring import PROGRAMS_FILE

    progs = {}
    for flex in (False, True):
        ro = reorient(flexible=flex)
        progs["flexible" if flex else "rigid"] = program_values(ro.T, ro.result.controls)
    with open(path or PROGRAMS_FILE, "w", encoding="utf-8") as fh:
        json.dump(progs, fh, indent=0)
    return progs
