"""``descent-fmus fly reentry``: fly the S1 closed loop through the FMUs."""
from __future__ import annotations

from pathlib import Path

from synthesis.cli import CliError, emit

FMU_DIR = Path(__file__).resolve().parents[2] / "fmus"


def register(sub) -> None:
    p = sub.add_parser("fly", help="fly a closed loop through the FMUs (default scenario)")
    p.add_argument("system", choices=["reentry"], help="system to fly")
    p.add_argument("--law", type=Path, help="law JSON file (network operator); default: the "
                   "paper's basic law with q1 = 2.259375, q2 = 1.953125")
    p.add_argument("--paper-law", action="store_true",
                   help="fly the paper's printed 16-node law (seed 000) instead of the basic law")
    p.add_argument("--q", type=float, nargs="+", help="override the law's parameters q")
    p.add_argument("--scenario", default="default", choices=["default", "second"],
                   help="entry conditions of SPEC S1 (default: V0 7500 m/s, h0 100 km, "
                        "beta0 -2.1 deg; second: 8000 m/s, 80 km, -1.6 deg)")
    p.add_argument("--fmus", type=Path, default=FMU_DIR, help="folder of the built FMUs")
    p.add_argument("--plot", type=Path, help="write a PNG of h(L), load(t) and u(t)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args) -> int:
    from synthesis.network_operator import LawFileError, NetworkOperator
    from synthesis.reentry_flight import fly, plot_flight

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
    res = fly(law, scenario=args.scenario, fmu_dir=args.fmus, record=bool(args.plot))
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
