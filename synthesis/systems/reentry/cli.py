"""``descent-fmus reentry fly | bound | robustness``."""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.cli_common import (CliError, add_common_options, emit, fmu_folder,
                                               positive_int)

__all__ = ["add_commands"]


def add_commands(sub) -> None:
    p = sub.add_parser("fly", help="fly one closed loop through the FMUs (default: the paper's "
                       "basic law, default scenario)")
    p.add_argument("--law", type=Path, help="law JSON file (network operator); default: the "
                   "paper's basic law with q1 = 2.259375, q2 = 1.953125")
    p.add_argument("--paper-law", action="store_true",
                   help="fly the paper's printed 16-node law instead of the basic law")
    p.add_argument("--q", type=float, nargs="+", help="override the law's parameters q")
    p.add_argument("--scenario", default="default", choices=["default", "second"],
                   help="entry conditions (default: V0 7500 m/s, h0 100 km, beta0 -2.1 deg; "
                        "second: 8000 m/s, 80 km, -1.6 deg)")
    add_common_options(p, plot="write a PNG of h(L), load(t) and u(t)")
    p.set_defaults(func=run_fly)

    o = sub.add_parser("bound", help="the best open-loop program u(t) (min max load at zero "
                       "miss): the bound for feedback laws")
    o.add_argument("--segments", type=positive_int, default=120)
    o.add_argument("--out", type=Path, default=None, metavar="FILE.json",
                   help="write the program as JSON")
    add_common_options(o, fmus=False, plot="PNG of u(t) and load(t)")
    o.set_defaults(func=run_bound)

    r = sub.add_parser("robustness", help="Monte-Carlo over the dispersion set through the "
                       "FMUs: laws vs the open-loop program flown blind")
    r.add_argument("--law", type=Path, action="append", default=[],
                   help="law JSON (repeatable); the paper's basic law is always flown too")
    r.add_argument("--program", type=Path, help="open-loop program JSON (reentry bound --out)")
    r.add_argument("--samples", type=positive_int, default=100)
    r.add_argument("--seed", type=int, default=7)
    add_common_options(r, plot="PNG of miss and max load per law")
    r.set_defaults(func=run_robustness)


def run_fly(args) -> int:
    from descent_fmus.synthesis.methods.network_operator import LawFileError, NetworkOperator
    from descent_fmus.synthesis.systems.reentry.flight import fly, plot_flight

    try:
        if args.law:
            law = NetworkOperator.load(args.law)
        else:
            law = NetworkOperator.paper_law() if args.paper_law else NetworkOperator.basic_law()
    except (OSError, LawFileError) as exc:
        raise CliError(f"cannot read law {args.law}: {exc}") from None
    if args.q:
        try:
            law = law.with_q(args.q)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    res = fly(law, scenario=args.scenario, fmu_dir=fmu_folder(args), record=bool(args.plot))
    summary = res.summary()
    if args.plot:
        plot_flight(res, args.plot)
        summary["plot"] = str(args.plot)
    text = (f"reentry ({args.scenario} scenario), law: {law.formula()}\n"
            f"  landed: {summary['landed']}  t_land = {summary['t_land']:.2f} s\n"
            f"  J1 (max load, paper's definition) = {summary['J1']:.4f}\n"
            f"  max aerodynamic load = {summary['aero_load_max']:.4f}\n"
            f"  range at hf = {summary['L_final'] / 1000:.3f} km, "
            f"miss J2 = {summary['J2'] / 1000:.3f} km")
    emit(args, summary, text)
    return 0


def run_bound(args) -> int:
    from descent_fmus.synthesis.systems.reentry.bound import optimize_open_loop, plot_program
    prog = optimize_open_loop(segments=args.segments)
    summary = prog.to_dict()
    summary.pop("u")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        prog.save(args.out)
        summary["program"] = str(args.out)
    if args.plot:
        plot_program(prog, args.plot)
        summary["plot"] = str(args.plot)
    emit(args, summary, f"open-loop optimum (N = {args.segments}): J1 = {prog.J1:.4f}, miss = "
         f"{prog.miss:.3g} m, landing at {prog.t_land:.2f} s ({prog.info['iterations']} SLSQP "
         f"iterations, {prog.info['seconds']:.1f} s)"
         + (f"; program written to {args.out}" if args.out else ""))
    return 0


def run_robustness(args) -> int:
    from descent_fmus.synthesis.methods.network_operator import LawFileError, NetworkOperator
    from descent_fmus.synthesis.systems.reentry.bound import Program
    from descent_fmus.synthesis.systems.reentry.robustness import dispersion_study, plot_study

    laws = {"basic law (paper q)": NetworkOperator.basic_law()}
    for path in args.law:
        try:
            laws[Path(path).stem if Path(path).name != "law.json" else str(Path(path).parent)] \
                = NetworkOperator.load(path)
        except (OSError, LawFileError) as exc:
            raise CliError(f"cannot read law {path}: {exc}") from None
    program = None
    if args.program:
        try:
            program = Program.load(args.program)
        except (OSError, ValueError) as exc:
            raise CliError(f"cannot read {args.program}: {exc}") from None
    study = dispersion_study(laws, program, args.samples, args.seed, fmu_folder(args))
    if args.plot:
        plot_study(study, args.plot)
    lines = [f"{'law':40s} {'miss median':>12s} {'miss p95':>10s} {'miss max':>10s} "
             f"{'J1 median':>10s} {'J1 max':>8s} {'landed':>7s}"]
    for name, s in study["stats"].items():
        lines.append(f"{name[:40]:40s} {s['miss_median'] / 1e3:10.2f}km "
                     f"{s['miss_p95'] / 1e3:8.2f}km "
                     f"{s['miss_max'] / 1e3:8.2f}km {s['J1_median']:10.3f} {s['J1_max']:8.3f} "
                     f"{s['landed_fraction']:7.0%}")
    emit(args, {"samples": args.samples, "seed": args.seed, "stats": study["stats"]},
         "\n".join(lines))
    return 0
