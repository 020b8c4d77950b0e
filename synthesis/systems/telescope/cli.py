"""``descent-fmus telescope reorient | route | write-programs``: the S4 reorientation and the
route problem by the direct method (Voronov 2009)."""
from __future__ import annotations

import math
from pathlib import Path

from descent_fmus.models.telescope_dynamics import T_DEFAULT, TARGET_W, TelescopeParams
from descent_fmus.synthesis.cli.common import (CliError, add_common_options,
                                               add_parameter_options, emit, finite_float,
                                               fmu_folder, int_at_least, parameter_overrides,
                                               positive_float, positive_int)
from descent_fmus.synthesis.systems.telescope.reorientation import (MAX_ITER, TOL_FLEXIBLE,
                                                                    TOL_RIGID, U_MAX_DEFAULT)

__all__ = ["add_commands", "PARAMETERS"]

#: Body parameters the reorient action takes as options (defaults from TelescopeParams).
PARAMETERS = ("h",)


def add_commands(sub) -> None:
    p = sub.add_parser("reorient", help="compute the CMG gimbal-rate program that reorients the "
                       "telescope (direct Newton-Kantorovich method)")
    p.add_argument("--flexible", action="store_true",
                   help="flexible telescope (2 panels x 2 modes), reduced algorithm")
    p.add_argument("--T", type=positive_float, default=T_DEFAULT,
                   help=f"reorientation time [s] (default {T_DEFAULT:g})")
    p.add_argument("--tol", type=positive_float,
                   help="tolerance on every component of lambda and omega (default "
                        f"{TOL_RIGID:g} rigid, {TOL_FLEXIBLE:g} flexible)")
    p.add_argument("--w-final", type=finite_float, nargs=3, metavar=("W1", "W2", "W3"),
                   help="final body rate [deg/s] (default "
                        + " ".join(f"{math.degrees(w):g}" for w in TARGET_W) + ")")
    p.add_argument("--max-iter", type=positive_int, default=MAX_ITER,
                   help=f"iteration limit (default {MAX_ITER})")
    add_parameter_options(p, TelescopeParams, PARAMETERS)
    p.add_argument("--u-max", type=positive_float, nargs="?", const=U_MAX_DEFAULT, default=None,
                   metavar="RAD_S", help="gimbal-rate limit |u_j(t)| <= u_max for every gyrodyne "
                   f"[rad/s] (the option alone: {U_MAX_DEFAULT:g}, which binds for the default "
                   "target)")
    p.add_argument("--min-energy", action="store_true",
                   help="the control of least integral |u|^2 dt among those meeting the end "
                        "conditions (Newton-KKT iterations of the direct method)")
    p.add_argument("--replay", action="store_true",
                   help="also fly the program through the FMUs with fmpy (needs built FMUs)")
    add_common_options(p, plot="write one PNG of u, omega, lambda, beta, the singularity "
                               "measure (the modal coordinates) and the miss per iteration")
    p.set_defaults(func=run_reorient)

    _add_route(sub)

    w = sub.add_parser("write-programs", help="solve the rigid and flexible reorientations and "
                       "store their programs: the defaults of the closed-loop FMUs")
    w.add_argument("--out", type=Path, default=None, metavar="FILE.json",
                   help="where to write (default: programs.json of the telescope package, "
                        "which build_fmus.py reads)")
    add_common_options(w, fmus=False)
    w.set_defaults(func=run_write_programs)


def _replayed(replay, solved, args) -> dict:
    """``replay(solved, fmu folder)``, its failures as one-line user errors."""
    from descent_fmus.synthesis.paths import FMUNotFoundError
    try:
        return replay(solved, fmu_folder(args))
    except (FMUNotFoundError, ValueError) as exc:
        raise CliError(f"cannot replay through the FMUs: {exc}") from None
    except KeyError as exc:            # FMUs built before a variable was added or renamed
        raise CliError(f"cannot replay through the FMUs: {exc.args[0]} (rebuild them: "
                       "python build_fmus.py)") from None


def run_reorient(args) -> int:
    from descent_fmus.synthesis.methods.direct_method import ConvergenceError
    from descent_fmus.synthesis.systems.telescope.reorientation import (UnreachableTargetError,
                                                                        plot_reorientation,
                                                                        reorient, replay)

    from descent_fmus.synthesis.systems.telescope.reorientation import RateLimitTooSmallError

    w_f = TARGET_W if args.w_final is None else tuple(math.radians(v) for v in args.w_final)
    params = TelescopeParams().with_(**parameter_overrides(args, PARAMETERS))
    try:
        ro = reorient(flexible=args.flexible, T=args.T, tol=args.tol, w_f=w_f, params=params,
                      max_iter=args.max_iter, u_max=args.u_max, min_energy=args.min_energy)
    except UnreachableTargetError as exc:
        raise CliError(f"unreachable target: {exc}") from None
    except RateLimitTooSmallError as exc:
        raise CliError(str(exc)) from None
    except ConvergenceError as exc:
        raise CliError(f"the direct method failed: {exc}") from None
    except ValueError as exc:          # an invalid parameter (ParameterError) or problem
        raise CliError(str(exc)) from None
    s = ro.summary()
    if args.replay:
        s.update(_replayed(replay, ro, args))
    if args.plot:
        s["plot"] = str(plot_reorientation(ro, args.plot))
    emit(args, s, "\n".join(_lines(s, args)))
    return 0


def _lines(s: dict, args) -> list[str]:
    lines = [f"S4 reorientation ({s['model']} model, T = {s['T']:g} s, tol {s['tol']:g}): "
             f"{s['iterations']} iterations in {s['seconds']:.3f} s "
             f"(paper: {s['paper_iterations']} iterations, {s['paper_seconds']} s on a 2009 CPU)"]
    for k, m in enumerate(s["miss_per_iteration"]):
        lines.append(f"  iteration {k}: max miss {m:.3e}")
    lines.append("  final errors: " + ", ".join(f"{k} {v:+.1e}"
                                                for k, v in s["final_errors"].items()))
    lines.append(f"  u(0) = u(T) = 0: {max(map(abs, s['u_start'] + s['u_end'])) == 0.0}, "
                 f"max |u| = {s['u_max_abs']:.4f} rad/s"
                 + (f" (limit {s['u_max']:g} rad/s)" if s["u_max"] is not None else "")
                 + f", integral |u|^2 dt = {s['energy']:.4f} rad^2/s"
                 + (" (minimum energy)" if s["min_energy"] else ""))
    lines.append(f"  invariants: ||lambda|-1| <= {s['lam_norm_drift']:.1e}, |K - K0| <= "
                 f"{s['momentum_drift']:.1e} N m s (relative {s['momentum_drift_relative']:.1e})")
    lines.append(f"  CMG singularity measure det(CC^T)/h^6: min {s['sing_min']:.3f} at t = "
                 f"{s['sing_min_time']:.1f} s (max possible 8; 0 = singular)")
    lines.append(f"  gyro momentum needed at T: {s['k_required']:.1f} of {s['envelope']:.1f} "
                 "N m s available in that direction")
    if args.flexible:
        lines.append(f"  rigid solution flown on the flexible model misses by "
                     f"{s['rigid_solution_on_flexible_miss']:.2e}; reduced algorithm from it: "
                     f"{s['iterations_from_rigid_solution']} iterations")
    if args.replay:
        lines.append(f"  FMU replay (fmpy): error vs target {s['replay_error_vs_target']:.1e}, "
                     f"vs solver {s['replay_error_vs_solver']:.1e}")
    if args.plot:
        lines.append(f"  plot: {s['plot']}")
    return lines


def run_write_programs(args) -> int:
    from descent_fmus.synthesis.systems.telescope.reorientation import write_programs
    from descent_fmus.synthesis.systems.telescope.wiring import PROGRAMS_FILE

    path = args.out or PROGRAMS_FILE
    progs = write_programs(path)
    summary = {"programs": str(path),
               "models": {k: {"n_nodes": v["n_nodes"], "t_end": v["t_end"]}
                          for k, v in progs.items()}}
    emit(args, summary, f"wrote {path}: " + ", ".join(
        f"{k} program ({v['n_nodes']} nodes over {v['t_end']:g} s)" for k, v in progs.items()))
    return 0


# -- route ---------------------------------------------------------------------------------------
def _add_route(sub) -> None:
    from descent_fmus.synthesis.methods.route_problem import JOINTS, RULES
    from descent_fmus.synthesis.systems.telescope.route import EPS, INTERVALS, PAPER_STAGES

    p = sub.add_parser("route", help="trace a route within eps: the telescope follows another "
                       "craft's reorientation (Voronov 2009, Example 3) as a chain of two-point "
                       "problems solved by the direct method")
    p.add_argument("--eps", type=positive_float, default=EPS,
                   help=f"allowed deviation from the route on lambda0..3 and omega (default "
                        f"{EPS:g}; the thesis needed {PAPER_STAGES} stages)")
    p.add_argument("--rule", choices=RULES, default="halving",
                   help="partition rule: halving (the thesis') or adaptive (stage length from the "
                        "measured deviation); default halving")
    p.add_argument("--joints", choices=JOINTS, default="continuous",
                   help="gimbal rates at the stage joints: continuous (default; a stage starts "
                        "with the rate the previous one ended with) or zero (u = 0 at every "
                        "joint)")
    p.add_argument("--u-max", type=positive_float, default=None, metavar="RAD_S",
                   help="gimbal-rate limit |u_j(t)| <= u_max [rad/s] on every stage")
    p.add_argument("--intervals", type=int_at_least(2), default=INTERVALS,
                   help=f"control intervals per stage (default {INTERVALS})")
    p.add_argument("--max-stages", type=positive_int, default=256,
                   help="no stage shorter than the route's duration / this (default 256)")
    p.add_argument("--w0", type=finite_float, nargs=3, metavar=("W1", "W2", "W3"),
                   help="the tracer's initial body rate [deg/s] (default: the route's; it must "
                        "be within eps of it)")
    p.add_argument("--replay", action="store_true",
                   help="also fly the traced program through the FMUs with fmpy and measure the "
                        "deviation there")
    add_common_options(p, plot="write one PNG of the gimbal rates with the stage joints, the "
                               "deviation from the route against eps and the route")
    p.set_defaults(func=run_route)


def run_route(args) -> int:
    from descent_fmus.synthesis.methods.direct_method import ConvergenceError
    from descent_fmus.synthesis.methods.route_problem import RouteError, RouteNotTracedError
    from descent_fmus.synthesis.systems.telescope.reorientation import RateLimitTooSmallError
    from descent_fmus.synthesis.systems.telescope.route import (plot_route, replay_route,
                                                                trace)

    w0 = None if args.w0 is None else tuple(math.radians(v) for v in args.w0)
    try:
        rt = trace(eps=args.eps, rule=args.rule, joints=args.joints, u_max=args.u_max,
                   intervals=args.intervals, max_stages=args.max_stages, w0=w0)
    except (RouteNotTracedError, RateLimitTooSmallError) as exc:
        raise CliError(str(exc)) from None
    except RouteError as exc:
        raise CliError(f"ill-posed route problem: {exc}") from None
    except ConvergenceError as exc:
        raise CliError(f"the direct method failed on the route craft's reorientation: "
                       f"{exc}") from None
    s = rt.summary()
    if args.replay:
        s.update(_replayed(replay_route, rt, args))
    if args.plot:
        s["plot"] = str(plot_route(rt, args.plot))
    lines = [f"S4 route (Voronov 2009, Example 3; eps {s['eps']:g}, rule {s['rule']}, joints "
             f"{s['joints']}): {s['stages']} stages (thesis: {s['paper_stages']}), max "
             f"deviation {s['max_deviation']:.3e} = {s['max_relative_deviation']:.3f} eps "
             f"(checked on {s['deviation_checked_at']})",
             f"  trace {s['seconds']:.2f} s ({s['stage_solves']} stage solves), route craft's "
             f"reorientation {s['route_seconds']:.2f} s ({s['route_iterations']} iterations)",
             "  stage joints tau [s]: " + " ".join(f"{v:.4g}" for v in s["tau"]),
             "  max deviation per component: " + ", ".join(
                 f"{k} {v:.1e}" for k, v in s["max_deviation_per_component"].items()),
             f"  max |u| = {s['u_peak']:.4f} rad/s"
             + (f" (limit {s['u_max']:g})" if s["u_max"] is not None else "")
             + f", integral |u|^2 dt = {s['energy']:.4f} rad^2/s, program nodes "
               f"{s['program_nodes']}; CMG singularity measure min {s['sing_min']:.2f}"]
    if args.replay:
        lines.append(f"  FMU replay (fmpy, step {s['replay_step']:.4g} s, {s['replay_points']} "
                     f"points): max deviation {s['replay_max_deviation']:.3e} = "
                     f"{s['replay_max_relative_deviation']:.3f} eps; end vs solver "
                     f"{s['replay_error_vs_solver']:.1e}")
    if args.plot:
        lines.append(f"  plot: {s['plot']}")
    emit(args, s, "\n".join(lines))
    return 0
