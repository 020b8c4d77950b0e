"""``descent-fmus synthesize NAME`` and the reentry companions ``optimize-open-loop`` and
``robustness``."""
from __future__ import annotations

from pathlib import Path

from synthesis.cli import CliError, emit

FMU_DIR = Path(__file__).resolve().parents[2] / "fmus"

#: Default budget: a useful result on a 2-core laptop in <= 15 minutes (see the note in
#: models/README.md for the measured run).
DEFAULTS = {"population": 256, "generations": 400, "crossovers": 32, "lchr": 8, "epoch": 12,
            "seed": 1}


def register(sub) -> None:
    p = sub.add_parser("synthesize", help="network-operator synthesis by the variational GA "
                       "(closed-loop FMU co-simulation as the evaluator)")
    p.add_argument("problem", help="synthesis problem (reentry, ...)")
    # default None: the problem's own budget (SynthesisProblem.defaults["ga"]), else DEFAULTS
    p.add_argument("--population", type=int, default=None)
    p.add_argument("--generations", type=int, default=None)
    p.add_argument("--crossovers", type=int, default=None,
                   help="crossover attempts per generation (4 children each)")
    p.add_argument("--lchr", type=int, default=None,
                   help="variations per individual (0 = parameter search of the basic law)")
    p.add_argument("--epoch", type=int, default=None,
                   help="generations between changes of the basic solution")
    p.add_argument("--wide-ops", action="store_true",
                   help="let variations use the authors' wider operation set (28 unary, 4 binary)")
    p.add_argument("--seed", type=int, default=None,
                   help="random seed (default: the problem's, else 1); same seed, same result")
    p.add_argument("--workers", type=int, default=2, help="local worker processes")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://HOST:PORT): evaluate on "
                   "that cluster instead of local processes")
    p.add_argument("--out", type=Path, default=Path("runs/synthesis"),
                   help="output directory (default runs/synthesis)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--fmus", type=Path, default=FMU_DIR, help="folder of the built FMUs")
    p.add_argument("--no-export", action="store_true", help="skip exporting the Pareto laws")
    p.add_argument("--open-loop", type=Path,
                   help="program JSON from optimize-open-loop (its J1 is the reported bound)")
    p.add_argument("--no-bound", action="store_true",
                   help="do not compute the open-loop bound for the report (reentry: ~20 s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run_synthesize)

    o = sub.add_parser("optimize-open-loop", help="best open-loop program u(t) (min max load at "
                       "zero miss): the bound for feedback laws")
    o.add_argument("problem", choices=["reentry"])
    o.add_argument("--segments", type=int, default=120)
    o.add_argument("--out", type=Path, default=Path("runs/open_loop.json"),
                   help="program JSON to write")
    o.add_argument("--plot", type=Path, help="PNG of u(t) and load(t)")
    o.add_argument("--json", action="store_true")
    o.set_defaults(func=run_open_loop)

    r = sub.add_parser("robustness", help="Monte-Carlo over the SPEC S1 dispersion set through "
                       "the FMUs: synthesised law vs basic law vs open-loop program flown blind")
    r.add_argument("problem", choices=["reentry"])
    r.add_argument("--law", type=Path, action="append", default=[],
                   help="law JSON (repeatable); default: the paper's basic law only")
    r.add_argument("--program", type=Path, help="open-loop program JSON (optimize-open-loop)")
    r.add_argument("--samples", type=int, default=100)
    r.add_argument("--seed", type=int, default=7)
    r.add_argument("--fmus", type=Path, default=FMU_DIR)
    r.add_argument("--plot", type=Path, help="PNG of miss and max load per law")
    r.add_argument("--json", action="store_true")
    r.set_defaults(func=run_robustness)


def run_synthesize(args) -> int:
    from synthesis.cosim import FMUNotFoundError
    from synthesis.evaluator import SchedulerError, get_problem
    from synthesis.ga import GAConfig
    from synthesis.open_loop import Program
    from synthesis.synthesize import RunDirError, run_synthesis

    try:
        problem = get_problem(args.problem)
        budget = dict(DEFAULTS, **problem.defaults.get("ga", {}))
        for key in DEFAULTS:
            if getattr(args, key) is None:
                setattr(args, key, budget[key])
        config = GAConfig(population=args.population, crossovers=args.crossovers,
                          lchr=args.lchr, epoch=args.epoch)
    except (KeyError, ValueError) as exc:
        raise CliError(str(exc).strip('"')) from None
    if args.generations < 0:
        raise CliError("--generations must be >= 0")
    ref = None
    if args.open_loop:
        try:
            ref = Program.load(args.open_loop).J1
        except (OSError, ValueError) as exc:
            raise CliError(f"cannot read {args.open_loop}: {exc}") from None
    try:
        summary = run_synthesis(args.problem, args.out, args.fmus, config, args.generations,
                                seed=args.seed, workers=args.workers, scheduler=args.scheduler,
                                resume=args.resume, wide_ops=args.wide_ops,
                                progress=not (args.quiet or args.json),
                                export=not args.no_export, reference_j1=ref,
                                bound=not args.no_bound)
    except (RunDirError, SchedulerError, FMUNotFoundError) as exc:
        raise CliError(str(exc)) from None
    short = {k: v for k, v in summary.items() if k != "pareto"}
    lines = [f"synthesis of {args.problem}: {summary['generations']} generations, "
             f"{summary['simulated']} closed-loop simulations in {summary['seconds']:.0f} s "
             f"({summary['evaluations_per_second']:.0f}/s), {summary['pareto_size']} Pareto laws",
             f"  results in {args.out}: pareto.csv, pareto.json, pareto.png, laws/<k>/"]
    for key in ("best_miss_below_1km", "ratio_to_open_loop"):
        if key in summary:
            lines.append(f"  {key}: {summary[key]}")
    emit(args, short, "\n".join(lines))
    return 0


def run_open_loop(args) -> int:
    from synthesis.open_loop import fly_program, optimize_open_loop
    if args.segments < 1:
        raise CliError("--segments must be >= 1")
    prog = optimize_open_loop(segments=args.segments)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    prog.save(args.out)
    summary = prog.to_dict()
    summary.pop("u")
    summary["program"] = str(args.out)
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np
        fi = fly_program(prog.u, prog.t_seg, trace=True)
        fig, ax = plt.subplots(1, 2, figsize=(11, 4))
        t = np.arange(len(prog.u)) * prog.t_seg
        ax[0].step(t, prog.u, where="post")
        ax[0].set(xlabel="t [s]", ylabel="u", title=f"best program, N = {len(prog.u)}")
        ax[1].plot(np.linspace(0, fi.t, len(fi.trace)), fi.trace)
        ax[1].set(xlabel="t [s] (samples)", ylabel="load", title=f"J1 = {prog.J1:.4f}")
        for a in ax:
            a.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        plt.close(fig)
        summary["plot"] = str(args.plot)
    emit(args, summary, f"open-loop optimum (N = {args.segments}): J1 = {prog.J1:.4f}, miss = "
         f"{prog.miss:.3g} m, landing at {prog.t_land:.2f} s ({prog.info['iterations']} SLSQP "
         f"iterations, {prog.info['seconds']:.1f} s); program written to {args.out}")
    return 0


def run_robustness(args) -> int:
    from synthesis.network_operator import LawFileError, NetworkOperator
    from synthesis.open_loop import Program
    from synthesis.robustness import dispersion_study, plot_study

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
    if args.samples < 1:
        raise CliError("--samples must be >= 1")
    study = dispersion_study(laws, program, args.samples, args.seed, args.fmus)
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
