"""``descent-fmus reentry fly | bound | robustness``."""
from __future__ import annotations

import argparse
from pathlib import Path

from descent_fmus.synthesis.cli.common import (CliError, add_common_options, emit, finite_float,
                                               fmu_folder, positive_float, positive_int)
from descent_fmus.synthesis.systems.reentry.error_families import FAMILIES
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law, paper_law

FAMILY_NAMES = tuple(FAMILIES)

__all__ = ["add_commands"]


def nonnegative_float(text: str) -> float:
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


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

    o = sub.add_parser("bound", help="the best open-loop programs u(t) on the controller's 1 s "
                       "grid (min true-peak max load): the bound at zero miss and the bound at "
                       "miss <= 1 km (the synthesis report's reference), read from the cache the "
                       "synthesis fills (computed and cached if missing)")
    o.add_argument("--t-seg", type=positive_float, default=None,
                   help="segment length [s] (default 1: the closed loop's sample period); "
                        "with --t-seg or --miss-tol one program is computed, not cached")
    o.add_argument("--miss-tol", type=nonnegative_float, default=None,
                   help="allowed miss |L(tf) - Lf| [m] (default: both bounds, 0 and 1000)")
    o.add_argument("--out", type=Path, default=None, metavar="FILE.json",
                   help="write the program as JSON (by default the one at zero miss)")
    add_common_options(o, fmus=False, plot="PNG of u(t) and load(t)")
    o.set_defaults(func=run_bound)

    r = sub.add_parser("robustness", help="guidance options over a held-out dispersion set "
                       "through the FMUs: laws (with the drag estimator if they read y3, with "
                       "the on-board correction if they read c), the NPC guidance, the blind "
                       "open-loop program, the oracle bound")
    r.add_argument("--law", type=Path, action="append", default=[],
                   help="law JSON of any S1 problem (repeatable); a law reading y3 flies with "
                        "the drag estimator; the paper's basic law is always flown too")
    r.add_argument("--guided", type=Path, action="append", default=[], metavar="LAW",
                   help="law JSON of y1, y2 (or y1, y2, y3) flown with the on-board "
                        "predictor-corrector correction c added (GuidedNetworkOperatorController;"
                        " repeatable); a law of reentry-guided (inputs y1, y2, y3, c) does so "
                        "with --law already")
    r.add_argument("--gate", type=finite_float, action="append", default=[],
                   metavar="G",
                   help="load gate [g] of the correction's braking (correction_gate): c > 0 "
                        "enters with the weight (1 - n/G)^2 below the drag load n = G, not "
                        "above it; 0 = no gate (the default).  Repeatable: every law with the "
                        "correction flies once per gate")
    r.add_argument("--replan", action="store_true",
                   help="every law with the correction c also flies with the on-board "
                        "re-planner (replan = 1: the correction a plan over altitude re-solved "
                        "every cycle for the least predicted peak load at zero predicted miss)")
    r.add_argument("--errors", nargs="+", metavar="FAMILY",
                   help="model-error families to fly instead of the scenarios' uniform sets: "
                        f"{', '.join(FAMILY_NAMES)} (a Latin-hypercube held-out set of each "
                        "around the --scenario's entry, the oracle bound and the load oracle "
                        "beside every option)")
    r.add_argument("--load-oracle", type=int, default=None, metavar="N",
                   help="with --errors: compute the load oracle (least peak load at zero miss, "
                        "~30 s a sample, cached) on the first N samples only (default all)")
    r.add_argument("--program", type=Path, help="open-loop program JSON of the default scenario "
                   "(reentry bound --out), flown blind")
    r.add_argument("--program-second", type=Path, metavar="FILE",
                   help="open-loop program JSON of the second scenario, flown blind")
    r.add_argument("--samples", type=positive_int, default=200,
                   help="held-out samples per scenario (default 200)")
    r.add_argument("--seed", type=int, default=7, help="seed of the held-out set (default 7; "
                   "the synthesis set is the nominal point + 15 uniform samples, seed 1: the sets "
                   "are disjoint)")
    r.add_argument("--scenario", choices=("default", "second", "both"), default="default",
                   help="entry conditions (second: V0 8000 m/s, h0 80 km, beta0 -1.6 deg)")
    r.add_argument("--no-npc", action="store_true", help="skip the NPC guidance")
    r.add_argument("--no-oracle", action="store_true", help="skip the oracle bound")
    r.add_argument("--noise", type=nonnegative_float, default=0.0, metavar="M/S2",
                   help="accelerometer white noise of the drag estimator (default 0)")
    r.add_argument("--bias", type=finite_float, default=0.0, metavar="M/S2",
                   help="accelerometer bias of the drag estimator (default 0)")
    add_common_options(r, plot="PNG of the miss CDFs against the oracle bound and J1 boxplots")
    r.set_defaults(func=run_robustness)


def run_fly(args) -> int:
    from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
    from descent_fmus.synthesis.systems.reentry.flight import fly, plot_flight

    try:
        if args.law:
            law = NetworkOperator.load(args.law)
        else:
            law = paper_law() if args.paper_law else paper_basic_law()
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
    from descent_fmus.synthesis.systems.reentry.bound import (T_SEG, optimize_open_loop,
                                                              plot_program)
    from descent_fmus.synthesis.systems.reentry.reports import BOUND_NAMES, bound_programs
    if args.t_seg is None and args.miss_tol is None:
        zero, tol, cached = bound_programs()
        summary = {"bound_at_zero_miss": _program_summary(zero),
                   "bound_at_miss_1km": _program_summary(tol),
                   "report_ratio_uses": "bound_at_miss_1km", "cache": str(cached[0].parent)
                   if cached[0] is not None else None}
        prog = zero
        text = "\n".join([f"{name}: J1 = {p.J1:.4f}, miss = {p.miss:.3g} m, landing at "
                           f"{p.t_land:.2f} s" for name, p in zip(BOUND_NAMES, (zero, tol))]
                          + [f"the synthesis report's ratio uses the {BOUND_NAMES[1]} (its best "
                             f"law is the best with miss < 1 km); best {len(zero.u)}-segment "
                             f"programs of {zero.t_seg:g} s, "
                             + (f"cached in {cached[0].parent}" if cached[0] is not None
                                else "computed (the cache folder is not writable)")])
    else:
        t_seg = T_SEG if args.t_seg is None else args.t_seg
        miss_tol = 0.0 if args.miss_tol is None else args.miss_tol
        prog = optimize_open_loop(t_seg=t_seg, miss_tol=miss_tol)
        summary = _program_summary(prog)
        text = (f"open-loop optimum ({len(prog.u)} segments of {prog.t_seg:g} s, miss "
                f"<= {miss_tol:g} m): J1 = {prog.J1:.4f}, miss = {prog.miss:.3g} m, landing at "
                f"{prog.t_land:.2f} s ({prog.info['iterations']} SLSQP iterations, "
                f"{prog.info['seconds']:.1f} s)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        prog.save(args.out)
        summary["program"] = str(args.out)
        text += (f"; program written to {args.out}" if args.t_seg or args.miss_tol is not None
                 else f"; the program of the {BOUND_NAMES[0]} written to {args.out}")
    if args.plot:
        plot_program(prog, args.plot)
        summary["plot"] = str(args.plot)
    emit(args, summary, text)
    return 0


def _program_summary(prog) -> dict:
    summary = prog.to_dict()
    summary.pop("u")
    return summary


def run_robustness(args) -> int:
    from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
    from descent_fmus.synthesis.systems.reentry.bound import Program
    from descent_fmus.synthesis.systems.reentry.guidance import reads_correction
    from descent_fmus.synthesis.systems.reentry.laws import as_guided

    bad = [g for g in args.gate if g < 0.0]
    if bad:
        raise CliError(f"--gate must be >= 0 g (0 = no gate), got {bad[0]:g}")
    laws, gated = {}, False
    for path, guided in [(p, False) for p in args.law] + [(p, True) for p in args.guided]:
        name = Path(path).stem if Path(path).name != "law.json" else str(Path(path).parent)
        try:
            law = NetworkOperator.load(path)
            if guided:
                law, name = as_guided(law), f"{name} + correction c"
        except (OSError, LawFileError, ValueError) as exc:
            raise CliError(f"cannot read law {path}: {exc}") from None
        if not reads_correction(law):
            laws[name] = law
            continue
        gated = True
        for gate in args.gate or [0.0]:
            laws[f"{name}, gate {gate:g} g" if gate else name] = \
                (law, {"correction_gate": gate}) if gate else law
        if args.replan:
            laws[f"{name}, re-planned"] = (law, {"replan": 1})
    if (args.gate or args.replan) and not gated:
        raise CliError("--gate and --replan apply to laws flown with the correction c (--guided "
                       "LAW, or a law of reentry-guided); none was given")
    programs = {}
    for scenario, path in (("default", args.program), ("second", args.program_second)):
        if path:
            try:
                programs[scenario] = Program.load(path)
            except (OSError, ValueError) as exc:
                raise CliError(f"cannot read {path}: {exc}") from None
    if args.errors:
        return _run_families(args, laws)
    from descent_fmus.synthesis.systems.reentry.robust_study import robust_study
    scenarios = ("default", "second") if args.scenario == "both" else (args.scenario,)
    study = robust_study(laws, args.samples, args.seed, fmu_folder(args), scenarios,
                         programs=programs, npc=not args.no_npc, oracle=not args.no_oracle,
                         noise=args.noise, bias=args.bias)
    return _emit_study(args, study)


def _emit_study(args, study) -> int:
    """Print (or emit as JSON) a study's table and statistics, and plot it with --plot."""
    from descent_fmus.synthesis.systems.reentry.robust_study import (plot_robust_study,
                                                                      table_lines)
    summary = {k: v for k, v in study.items() if k != "scenarios"}
    summary["scenarios"] = {n: {"stats": sc["stats"]} for n, sc in study["scenarios"].items()}
    if args.plot:
        plot_robust_study(study, args.plot)
        summary["plot"] = str(args.plot)
    emit(args, summary, "\n".join(table_lines(study)))
    return 0


def _run_families(args, laws) -> int:
    """``reentry robustness --errors FAMILY...``: each family's held-out set (family_study)."""
    from descent_fmus.synthesis.systems.reentry.family_study import family_study
    bad = [f for f in args.errors if f not in FAMILIES]
    if bad:
        raise CliError(f"unknown error family {bad[0]!r}; choose from {', '.join(FAMILIES)}")
    if args.load_oracle is not None and args.load_oracle < 0:
        raise CliError(f"--load-oracle must be >= 0, got {args.load_oracle}")
    if args.scenario == "both":
        raise CliError("--errors flies one scenario at a time: --scenario default or second")
    from descent_fmus.synthesis.systems.reentry.robust_study import SCENARIOS
    study = family_study(laws, args.errors, args.samples, args.seed, fmu_folder(args),
                         npc=not args.no_npc, oracle=not args.no_oracle,
                         load_oracle=args.load_oracle, base=SCENARIOS[args.scenario])
    return _emit_study(args, study)
