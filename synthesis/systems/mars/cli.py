"""``descent-fmus mars``: fly the S2 Mars descent with and without the law through the FMUs."""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.cli import CliError, emit


def register(sub) -> None:
    from descent_fmus.synthesis.systems.mars.flight import FMU_DIR, FORMULAS
    p = sub.add_parser("mars", help="S2 Mars capsule: alpha(t) with and without the Bellman "
                       "law, through the FMUs")
    p.add_argument("--no-control", action="store_true",
                   help="fly only the uncontrolled descent (u = 0)")
    p.add_argument("--formula", choices=sorted(FORMULAS) + ["both"], default="consistent",
                   help="gain A of the law: the consistent root of eq. (14) (default), the "
                        "paper's printed root (15) with its guards, or both")
    p.add_argument("--alpha0", type=float, help="initial angle of attack [rad] (default 0.2)")
    p.add_argument("--omega-x", type=float, help="roll rate [rad/s] (default 5)")
    p.add_argument("--b", type=float, help="weight b of alpha^2 (default 1)")
    p.add_argument("--c", type=float, help="weight c of u^2 (default 100)")
    p.add_argument("--u-max", type=float, help="saturation of |u| (default 0.01)")
    p.add_argument("--fmus", type=Path, default=FMU_DIR, help="folder of the built FMUs")
    p.add_argument("--plot", type=Path, help="write a PNG of alpha(t) and u(t) of all runs")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args) -> int:
    from descent_fmus.synthesis.cosim import FMUError, FMUNotFoundError
    from descent_fmus.synthesis.systems.mars.flight import fly_set, plot_alpha

    plant, ctrl = {}, {}
    for opt, dest, name in (("alpha0", plant, "alpha0"), ("omega_x", plant, "omega_x"),
                            ("b", ctrl, "b"), ("c", ctrl, "c"), ("u_max", ctrl, "u_max")):
        v = getattr(args, opt)
        if v is not None:
            dest[name] = v
    formulas = ("consistent", "paper") if args.formula == "both" else (args.formula,)
    try:
        runs = fly_set(args.fmus, control=not args.no_control, formulas=formulas,
                       plant_values=plant, controller_values=ctrl, record=bool(args.plot))
    except FMUNotFoundError as exc:
        raise CliError(str(exc)) from None
    except FMUError as exc:
        raise CliError(f"the flight failed: {exc}") from None
    summary = {"runs": [r.summary() for r in runs]}
    base = runs[0].alpha_end
    lines = [f"S2 Mars descent to h_end (t_end = {runs[0].result.final['t_end']:.1f} s), "
             f"through the FMUs:"]
    for r in runs:
        lines.append(f"  {r.label:<22} alpha_end = {r.alpha_end:.3e} rad "
                     f"({r.summary()['alpha_end_deg']:.4f} deg)")
    if len(runs) > 1:
        ctl = runs[1].alpha_end
        summary["ratio_uncontrolled_to_controlled"] = base / ctl if ctl > 0 else float("inf")
        lines.append(f"  ratio no control / law ({runs[1].label}) = "
                     f"{summary['ratio_uncontrolled_to_controlled']:.3g}")
    if args.plot:
        plot_alpha(runs, args.plot)
        summary["plot"] = str(args.plot)
        lines.append(f"  plot: {args.plot}")
    emit(args, summary, "\n".join(lines))
    return 0
