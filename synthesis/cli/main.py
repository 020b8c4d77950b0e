"""Command line of descent-fmus.

One pattern: general commands act on any problem, system commands are
``descent-fmus <system> <action>``::

    descent-fmus synthesize NAME | --problem FILE.toml --out DIR   network-operator synthesis
    descent-fmus problems                                          registered problems, systems
    descent-fmus info SYSTEM                                       FMUs and parameter tables
    descent-fmus reentry fly | bound | robustness
    descent-fmus mars fly
    descent-fmus lunar-landing solve | fly
    descent-fmus telescope reorient | route | write-programs
    descent-fmus lunar-descent report

Every command takes ``--json``; ``--plot FILE.png`` writes a figure (nothing is written unless
asked).  A user error ends with one line and exit code 2; a run stopped by SIGINT/SIGTERM keeps
its checkpoint, says how to resume and exits with 130/143.
"""
from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from descent_fmus.synthesis.cli.common import (CliError, OneLineParser, add_common_options,
                                               emit, fmu_folder, nonnegative_int, positive_int)

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    from descent_fmus.synthesis.registry import all_systems
    ap = OneLineParser(prog="descent-fmus", description=__doc__.splitlines()[0],
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog="\n".join(__doc__.splitlines()[2:]))
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND",
                            parser_class=OneLineParser)
    _add_synthesize(sub)
    from descent_fmus.synthesis.fmi.law_files import add_export_law_command
    add_export_law_command(sub)
    from descent_fmus.synthesis.cli.fine_output import add_fine_output_command
    add_fine_output_command(sub)
    p = sub.add_parser("problems", help="list the registered synthesis problems and systems")
    add_common_options(p, fmus=False)
    p.set_defaults(func=run_problems)
    p = sub.add_parser("info", help="a system's FMUs, closed loops and parameter tables "
                       "(Markdown)")
    p.add_argument("system", help="system name (reentry, mars, lunar-landing, telescope, "
                   "lunar-descent)")
    add_common_options(p, fmus=False)
    p.set_defaults(func=run_info)
    for system in all_systems():
        if system.add_commands is None:
            continue
        sp = sub.add_parser(system.cli_name, help=system.title)
        actions = sp.add_subparsers(dest="action", required=True, metavar="ACTION",
                                    parser_class=OneLineParser)
        system.add_commands(actions)
    return ap


# -- synthesize -----------------------------------------------------------------------------------
def _add_synthesize(sub) -> None:
    p = sub.add_parser("synthesize", help="network-operator synthesis by the variational GA "
                       "(the closed-loop FMU co-simulation is its evaluator)")
    p.add_argument("name", nargs="?", help="registered problem (descent-fmus problems lists "
                   "them); or give --problem FILE")
    p.add_argument("--problem", type=Path, metavar="FILE.toml",
                   help="a problem file for any FMI 2.0 co-simulation plant FMU")
    g = p.add_argument_group("budget (default: the problem's own)")
    g.add_argument("--population", type=positive_int, default=None)
    g.add_argument("--generations", type=nonnegative_int, default=None)
    g.add_argument("--crossovers", type=positive_int, default=None,
                   help="crossover attempts per generation (4 children each)")
    g.add_argument("--lchr", type=nonnegative_int, default=None,
                   help="variations per individual (0 = parameter search of the basic law)")
    g.add_argument("--epoch", type=positive_int, default=None,
                   help="generations between changes of the basic solution")
    g.add_argument("--seed", type=int, default=None, help="random seed; same seed, same result")
    g.add_argument("--refine-basis", type=nonnegative_int, default=None, metavar="N",
                   help="CMA-ES evaluations on the basic solution's parameters before the "
                        "structure search (0 = none)")
    g.add_argument("--refine-evals", type=nonnegative_int, default=None,
                   help="CMA-ES evaluations per parameter refinement inside the GA (0 = the "
                        "GA alone)")
    g.add_argument("--flights", type=nonnegative_int, default=None,
                   help="flight budget (laws flown, each over all the problem's initial "
                        "states): a cma-* method flies this many; the network operator stops "
                        "there too (0 = by generations)")
    p.add_argument("--statistic", default=None, metavar="NAME",
                   help="statistic of the miss over the sample set, for problems judged on one "
                        "(reentry-sensed, -sensed-y12, -guided): mean, median, p75, p90, max")
    p.add_argument("--method", default="network-operator",
                   help="network-operator (default: the variational GA) or cma-<baseline>: "
                        "CMA-ES over the parameters of one of the problem's fixed structures "
                        "(reentry: cma-basic, cma-polynomial, cma-tanh), same evaluator")
    p.add_argument("--wide-ops", action="store_true",
                   help="let variations use the authors' wider operation set (28 unary, 4 binary)")
    p.add_argument("--workers", type=positive_int, default=2, help="local worker processes")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://HOST:PORT): evaluate on "
                   "that cluster instead of local processes (its workers need only the "
                   "installed package; the FMUs are shipped); 'local': a Dask LocalCluster of "
                   "--workers processes")
    p.add_argument("--out", type=Path, default=Path("runs/synthesis"),
                   help="output folder (default runs/synthesis)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--no-export", action="store_true", help="skip exporting the Pareto laws")
    p.add_argument("--export", choices=("laws", "all"), default="laws",
                   help="per Pareto law: 'laws' = law.json (with the readable formula), "
                        "law.h/law.c and the law FMU (default); 'all' = also its closed-loop "
                        "FMU and SSP (about 1.7 MB a law)")
    p.add_argument("--law-fmu", choices=("native", "python"), default=None,
                   help="the law FMUs: native C (default where a C compiler exists) or the "
                        "pythonfmu controller with the law as defaults")
    p.add_argument("--no-reference", action="store_true",
                   help="skip the problem's expensive report reference (reentry: the open-loop "
                        "bound, ~20 s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_common_options(p)
    p.set_defaults(func=run_synthesize)


def load_problem(args):
    """The problem named on the command line or given as a file (CliError otherwise)."""
    from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file
    from descent_fmus.synthesis.registry import UnknownProblemError, get_problem
    if (args.name is None) == (args.problem is None):
        raise CliError("give a registered problem name or --problem FILE (one of them); "
                       "'descent-fmus problems' lists the names")
    if args.problem is not None:
        try:
            return load_problem_file(args.problem, fmu_dir=fmu_folder(args))
        except ProblemFileError as exc:
            raise CliError(str(exc)) from None
    try:
        return get_problem(args.name)
    except UnknownProblemError as exc:
        raise CliError(str(exc)) from None


def with_statistic(problem, name):
    """``problem`` judged with the set statistic ``name`` (None: unchanged); CliError if the
    problem has no set statistic or the name is unknown."""
    if name is None:
        return problem
    from dataclasses import replace
    if not hasattr(problem.objectives, "statistic"):
        raise CliError(f"problem {problem.name} is not judged on a sample set: --statistic "
                       f"does not apply")
    try:
        objectives = replace(problem.objectives, statistic=name)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    labels = problem.labels[:1] + (f"J2 = {name} miss over the set [m]",) + problem.labels[2:]
    return problem.with_(objectives=objectives, objective_labels=labels,
                         source=f"{problem.source}, statistic {name}")


def _law_export(args):
    """What ``synthesize`` exports per Pareto law (``--no-export``, ``--export``,
    ``--law-fmu``); a compiler missing for ``--law-fmu native`` is a user error."""
    from descent_fmus.synthesis.fmi.law_files import LawExport, choose_law_fmu
    from descent_fmus.synthesis.fmi.native.build import CompilerNotFoundError
    if args.no_export:
        return False
    try:
        choose_law_fmu(args.law_fmu or "auto")
    except CompilerNotFoundError as exc:
        raise CliError(str(exc)) from None
    return LawExport(law_fmu=args.law_fmu or "auto", closed_loops=args.export == "all")


def run_synthesize(args) -> int:
    from descent_fmus.synthesis.run.evaluation import SchedulerError, SystematicFailure
    from descent_fmus.synthesis.paths import FMUNotFoundError
    from descent_fmus.synthesis.run.loop import RunDirError, run_synthesis

    problem = with_statistic(load_problem(args), args.statistic)
    try:
        budget = problem.budget.with_(population=args.population,
                                      generations=args.generations,
                                      crossovers=args.crossovers, lchr=args.lchr,
                                      epoch=args.epoch, seed=args.seed,
                                      flights=args.flights, refine_evals=args.refine_evals,
                                      refine_basis=args.refine_basis)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    from descent_fmus.synthesis.run.loop import methods
    if args.method not in methods(problem):
        raise CliError(f"unknown method {args.method!r} for problem {problem.name}; available: "
                       f"{', '.join(methods(problem))}")
    if args.method != "network-operator" and budget.flights < 1:
        raise CliError(f"method {args.method} needs a flight budget: give --flights N")
    try:
        summary = run_synthesis(problem, args.out, fmu_folder(args), budget,
                                workers=args.workers, scheduler=args.scheduler,
                                resume=args.resume, wide_ops=args.wide_ops,
                                progress=not (args.quiet or args.json),
                                export=_law_export(args), reference=not args.no_reference,
                                method=args.method)
    except (RunDirError, SchedulerError, FMUNotFoundError, SystematicFailure) as exc:
        raise CliError(str(exc)) from None
    short = {k: v for k, v in summary.items() if k != "pareto"}
    lines = [f"synthesis of {problem.name} ({args.method}): {summary['generations']} "
             f"generations, "
             f"{summary['simulated']} closed-loop simulations in {summary['seconds']:.0f} s "
             f"({summary['evaluations_per_second']:.0f}/s, {summary['failures']} failed), "
             f"{summary['pareto_size']} Pareto laws",
             f"  results in {args.out}: pareto.csv, pareto.json, pareto.png, summary.json"
             + (", laws/<k>/" if not args.no_export else "")]
    if summary.get("first_failure"):       # failed candidates were penalised: the first reason
        lines.append(f"  first failed evaluation: {summary['first_failure']}")
    if summary.get("law_fmu_note"):
        lines.append(f"  note: {summary['law_fmu_note']}")
    lines += problem.report.lines(summary)
    emit(args, short, "\n".join(lines))
    return 0


# -- listings ---------------------------------------------------------------------------------------
def run_problems(args) -> int:
    from descent_fmus.synthesis.registry import all_systems
    systems, problems = [], []
    for s in all_systems():
        systems.append({"system": s.cli_name, "title": s.title,
                        "fmus": [f.split(":")[1] for f in s.fmus],
                        "closed_loops": [c.wiring.name for c in s.closed_loops]})
        for pb in (s.problems() if s.problems else ()):
            problems.append({"problem": pb.name, "system": s.cli_name,
                             "description": pb.description,
                             "objectives": list(pb.objective_names),
                             "initial_states": len(pb.initial_states)})
    lines = ["synthesis problems (descent-fmus synthesize NAME; any plant FMU: --problem "
             "FILE.toml):"]
    lines += [f"  {p['problem']:16s} {p['description']}" for p in problems]
    lines.append("systems (descent-fmus SYSTEM --help):")
    lines += [f"  {s['system']:16s} {s['title']}" for s in systems]
    emit(args, {"problems": problems, "systems": systems}, "\n".join(lines))
    return 0


def run_info(args) -> int:
    from descent_fmus.synthesis.cli.info import system_info
    from descent_fmus.synthesis.registry import get_system
    try:
        system = get_system(args.system)
    except KeyError as exc:
        raise CliError(exc.args[0]) from None
    info, text = system_info(system)
    emit(args, info, text)
    return 0


def main(argv=None) -> int:
    # The command line chooses the matplotlib backend (files only); library code never does.
    os.environ.setdefault("MPLBACKEND", "Agg")
    from descent_fmus.models.controllers.network_operator import MatrixError
    from descent_fmus.models.params import ParameterError
    from descent_fmus.synthesis.fmi.closed_loop import FMUError
    from descent_fmus.synthesis.run.signals import RunInterrupted

    import faulthandler
    if not faulthandler.is_enabled():
        # a crash inside an FMU's native code prints the Python stack it happened in
        faulthandler.enable()
    ap = build_parser()
    args = ap.parse_args(argv)
    name = args.command + (f" {args.action}" if getattr(args, "action", None) else "")
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"descent-fmus {name}: error: {exc}", file=sys.stderr)
        return 2
    except (OSError, FMUError, ParameterError, MatrixError) as exc:
        # user-facing failures (a missing FMU or folder, a file that cannot be written, an FMU
        # rejecting a value): one line, no traceback
        print(f"descent-fmus {name}: error: {exc}", file=sys.stderr)
        return 2
    except RunInterrupted as exc:
        # a run stopped on SIGTERM/SIGINT: where it stands and how to continue, one line
        argv = list(sys.argv[1:] if argv is None else argv)
        how = (" -- continue with: descent-fmus " + shlex.join(
            argv + ([] if "--resume" in argv else ["--resume"])))
        print(f"descent-fmus {name}: {exc}" + (how if getattr(exc, "resumable", False) else ""),
              file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"descent-fmus {name}: interrupted", file=sys.stderr)
        return 130


def entry() -> None:
    """The ``descent-fmus`` program: :func:`main`, then the process ends right after its exit
    handlers have run.

    The exit handlers free the FMUs loaded in this process and remove their folders, and every
    result is written by then.  The interpreter's own teardown is skipped: with pythonfmu FMUs
    loaded in the process (``--workers 1``) it was seen, rarely, to abort in glibc's heap checks
    ("corrupted double-linked list") after a run had finished and written everything -- an
    exit status that would have reported a good run as a crash.
    """
    try:
        code = main()
    except SystemExit as exc:          # argparse: --help, usage errors
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        if exc.code is not None and not isinstance(exc.code, int):
            print(exc.code, file=sys.stderr)
    exit_without_teardown(code)


def exit_without_teardown(code) -> None:
    """End the process with ``code`` once the exit handlers have run and the output is
    flushed, skipping the interpreter's teardown (see :func:`entry`: with pythonfmu FMUs loaded
    in the process, glibc's heap checks were seen, rarely, to abort it after all work was
    done).  The test session ends the same way (``tests/conftest.py``)."""
    import atexit
    atexit._run_exitfuncs()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(code or 0))


if __name__ == "__main__":
    entry()
