"""``descent-fmus reorient``: S4 telescope reorientation by the direct method (seed 003)."""
from __future__ import annotations

import math
from pathlib import Path

from descent_fmus.synthesis.cli import CliError, emit

FMU_DIR = Path(__file__).resolve().parents[2] / "fmus"


def register(sub) -> None:
    p = sub.add_parser("reorient", help="S4: compute the CMG gimbal-rate program that reorients "
                       "the telescope (direct Newton-Kantorovich method)")
    p.add_argument("--flexible", action="store_true",
                   help="flexible telescope (2 panels x 2 modes), reduced algorithm")
    p.add_argument("--T", type=float, default=40.0, help="reorientation time [s] (default 40)")
    p.add_argument("--tol", type=float, help="tolerance on every component of lambda and omega "
                   "(default 1e-7 rigid, 1e-8 flexible)")
    p.add_argument("--w-final", type=float, nargs=3, metavar=("W1", "W2", "W3"),
                   help="final body rate [deg/s] (default -0.3 0 -0.3)")
    p.add_argument("--max-iter", type=int, default=20, help="iteration limit (default 20)")
    p.add_argument("--replay", action="store_true",
                   help="also fly the program through the FMUs with fmpy (needs built FMUs)")
    p.add_argument("--fmus", type=Path, default=FMU_DIR, help="folder of the built FMUs")
    p.add_argument("--plot", type=Path, metavar="DIR",
                   help="write PNGs of u, omega, lambda, beta, singularity measure, miss")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args) -> int:
    from descent_fmus.models.telescope import TARGET_W
    from descent_fmus.synthesis.methods.direct_method import ConvergenceError
    from descent_fmus.synthesis.systems.telescope.reorientation import UnreachableTargetError, plot_reorientation, reorient, \
        replay

    w_f = TARGET_W if args.w_final is None else tuple(math.radians(v) for v in args.w_final)
    try:
        ro = reorient(flexible=args.flexible, T=args.T, tol=args.tol, w_f=w_f,
                      max_iter=args.max_iter)
    except UnreachableTargetError as exc:
        raise CliError(f"unreachable target: {exc}") from None
    except ConvergenceError as exc:
        raise CliError(f"the direct method failed: {exc}") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None
    s = ro.summary()
    if args.replay:
        from descent_fmus.synthesis.cosim import FMUNotFoundError
        try:
            s.update(replay(ro, args.fmus))
        except (FMUNotFoundError, ValueError) as exc:
            raise CliError(f"cannot replay through the FMUs: {exc}") from None
    if args.plot:
        s["plots"] = [str(p) for p in plot_reorientation(ro, args.plot)]
    lines = [f"S4 reorientation ({s['model']} model, T = {s['T']:g} s, tol {s['tol']:g}): "
             f"{s['iterations']} iterations in {s['seconds']:.3f} s "
             f"(paper: {s['paper_iterations']} iterations, {s['paper_seconds']} s on a 2009 CPU)"]
    for k, m in enumerate(s["miss_per_iteration"]):
        lines.append(f"  iteration {k}: max miss {m:.3e}")
    lines.append("  final errors: " + ", ".join(f"{k} {v:+.1e}"
                                                for k, v in s["final_errors"].items()))
    lines.append(f"  u(0) = u(T) = 0: {max(map(abs, s['u_start'] + s['u_end'])) == 0.0}, "
                 f"max |u| = {math.degrees(s['u_max_abs']):.2f} deg/s")
    lines.append(f"  invariants: ||lambda|-1| <= {s['lam_norm_drift']:.1e}, |K - K0| <= "
                 f"{s['momentum_drift']:.1e} N m s (relative {s['momentum_drift_relative']:.1e})")
    lines.append(f"  CMG singularity measure det(CC^T)/h^6: min {s['sing_min']:.3f} at t = "
                 f"{s['sing_min_time']:.1f} s (max possible 8; 0 = singular)")
    lines.append(f"  gyro momentum needed at T: {s['k_required']:.1f} of {s['envelope']:.1f} N m s "
                 "available in that direction")
    if args.flexible:
        lines.append(f"  rigid solution flown on the flexible model misses by "
                     f"{s['rigid_solution_on_flexible_miss']:.2e}; reduced algorithm from it: "
                     f"{s['iterations_from_rigid_solution']} iterations")
    if args.replay:
        lines.append(f"  FMU replay (fmpy): error vs target {s['replay_error_vs_target']:.1e}, "
                     f"vs solver {s['replay_error_vs_solver']:.1e}")
    if args.plot:
        lines.append("  plots: " + ", ".join(s["plots"]))
    emit(args, s, "\n".join(lines))
    return 0
