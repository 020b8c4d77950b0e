"""``descent-fmus synthesize``: run a synthesis method on a registered problem or a problem file.

The recipe options (``--flights``, ``--population``, ``--refine-evals``, ...) are derived from the
settings dataclasses of the problem contract (:data:`~synthesis.problems.contract.SETTING_GROUPS`):
their names, help texts and documented limits are written once, there.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from descent_fmus.synthesis.cli.common import (CliError, add_common_options, emit, fmu_folder,
                                               int_at_least)
from descent_fmus.synthesis.run.resources import MAX_WORKERS

__all__ = ["add_synthesize_command", "load_problem", "run_synthesize", "apply_options"]


def _setting_type(info, flag: str):
    """An argparse type for one setting: its type, checked against its limits."""
    def convert(text: str):
        try:
            v = info.type(text)
        except ValueError:
            what = "an integer" if info.type is int else "a number"
            raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None
        if info.choices is not None and v not in info.choices:
            raise argparse.ArgumentTypeError(f"must be one of {info.limits}, got {text!r}")
        if info.minimum is not None and v < info.minimum:
            raise argparse.ArgumentTypeError(f"must be >= {info.minimum}, got {text!r}")
        if info.maximum is not None and v > info.maximum:
            raise argparse.ArgumentTypeError(f"must be <= {info.maximum} (the documented "
                                             f"maximum), got {text!r}")
        return v
    convert.__name__ = flag
    return convert


def _operations(binary: bool):
    """An argparse type: comma-separated operation names or numbers -> their numbers."""
    def convert(text: str) -> tuple:
        from descent_fmus.models.controllers.operation_table import (OperationNameError,
                                                                     operation_numbers)
        try:
            return operation_numbers(text.split(","), binary=binary)
        except OperationNameError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    convert.__name__ = "binary" if binary else "unary"
    return convert


def _add_setting_options(p) -> None:
    from descent_fmus.synthesis.methods.settings import settings_of
    from descent_fmus.synthesis.problems.contract import SETTING_GROUPS
    titles = {"budget": "budget (default: the problem's own)",
              "ga": "variational GA (default: the problem's own)",
              "refine": "CMA-ES refinement inside the GA (default: the problem's own)",
              "gp": "genetic-programming baseline, --method gp (default: the problem's own)"}
    for attr, cls, prefix in SETTING_GROUPS:
        g = p.add_argument_group(titles[attr])
        for info in settings_of(cls):
            flag = "--" + (prefix + info.name).replace("_", "-")
            str_type = info.type is str and info.choices is None
            g.add_argument(flag, dest=prefix + info.name, default=None,
                           type=str if str_type else _setting_type(info, flag),
                           metavar=None if info.choices else "N" if info.type is int else "X",
                           choices=info.choices, help=f"{info.help} [{info.limits}]")


def add_synthesize_command(sub) -> None:
    p = sub.add_parser("synthesize", help="synthesise a feedback law (network-operator GA or a "
                       "CMA-ES baseline), the closed-loop FMU co-simulation as its evaluator")
    p.add_argument("name", nargs="?", help="registered problem (descent-fmus problems lists "
                   "them); or give --problem FILE")
    p.add_argument("--problem", type=Path, metavar="FILE.toml",
                   help="a problem file for any FMI 2.0 co-simulation plant FMU")
    _add_setting_options(p)
    p.add_argument("--method", default="network-operator",
                   help="network-operator (default: the variational GA), cma-<structure>: "
                        "CMA-ES over the parameters of one of the problem's fixed structures "
                        "(descent-fmus problems lists them), or gp: genetic programming; same "
                        "evaluator")
    p.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                   help="a variant the problem offers (descent-fmus problems lists them), e.g. "
                        "statistic=median for the sample-set problems")
    p.add_argument("--statistic", default=None, metavar="NAME",
                   help="shorthand for --option statistic=NAME")
    p.add_argument("--input-scaling", choices=("auto", "given"), default=None,
                   help="the law's input coordinates: 'auto' derives them from the basic law's "
                        "flights (where it acts unsaturated), 'given' keeps the problem's "
                        "(default: the problem's own)")
    p.add_argument("--wide-ops", action="store_true",
                   help="let variations use the authors' wider operation set (28 unary, 4 binary)")
    p.add_argument("--unary", metavar="OPS", default=None, type=_operations(False),
                   help="the unary operations variations may use, names or numbers separated by "
                        "commas, e.g. id,neg,sin,cos,wrap (default: the problem's own; "
                        "docs/methods/network_operator.md lists them)")
    p.add_argument("--binary", metavar="OPS", default=None, type=_operations(True),
                   help="the binary operations variations may use, e.g. add,mul,atan2,hypot")
    p.add_argument("--workers", type=int_at_least(1, MAX_WORKERS), default=2,
                   help=f"local worker processes [1..{MAX_WORKERS}]")
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


def apply_options(problem, args):
    """``problem`` with the command line's ``--option``/``--statistic`` variants, recipe
    settings, ``--wide-ops`` and ``--unary``/``--binary`` (CliError for anything it cannot
    take)."""
    from descent_fmus.synthesis.methods.settings import SettingError, settings_of
    from descent_fmus.synthesis.methods.ga_config import WIDE_BINARY, WIDE_UNARY
    from descent_fmus.synthesis.problems.contract import SETTING_GROUPS
    options = list(args.option) + ([f"statistic={args.statistic}"] if args.statistic else [])
    for text in options:
        name, eq, value = text.partition("=")
        if not eq:
            raise CliError(f"--option takes NAME=VALUE, got {text!r}")
        try:
            problem = problem.with_option(name.strip(), value.strip())
        except ValueError as exc:
            raise CliError(str(exc)) from None
    changes = {prefix + s.name: getattr(args, prefix + s.name, None)
               for _, cls, prefix in SETTING_GROUPS for s in settings_of(cls)}
    try:
        problem = problem.tuned(**changes)
    except SettingError as exc:
        raise CliError(str(exc)) from None
    if args.wide_ops:
        problem = problem.with_(unary=WIDE_UNARY, binary=WIDE_BINARY)
    for kind in ("unary", "binary"):
        if getattr(args, kind, None) is not None:
            problem = problem.with_(**{kind: args.__dict__[kind]})
    if args.input_scaling:
        problem = problem.with_(input_scaling=args.input_scaling)
    return problem


def _law_export(args):
    """What ``synthesize`` exports per Pareto law (``--no-export``, ``--export``,
    ``--law-fmu``); a compiler missing for ``--law-fmu native`` is a user error."""
    from descent_fmus.synthesis.fmi.law_files import LawExport, choose_law_fmu
    from descent_fmus.synthesis.fmi.native.builders.build import CompilerNotFoundError
    if args.no_export:
        return False
    try:
        choose_law_fmu(args.law_fmu or "auto")
    except CompilerNotFoundError as exc:
        raise CliError(str(exc)) from None
    return LawExport(law_fmu=args.law_fmu or "auto", closed_loops=args.export == "all")


def _warm_interpreter(export) -> None:
    """[choice] The export's one compile -- the native network-operator interpreter FMU, built
    once per machine into the cache folder (~2 s of the C compiler) -- starts with the run, in
    a thread of this process, so that a fresh machine's first run does not wait for it after
    the search (the export takes the same FMU, waiting only if the compile is still going)."""
    import threading

    from descent_fmus.synthesis.fmi.law_files import LawExport, choose_law_fmu
    what = LawExport.of(export)
    if what is None or what.compiled or choose_law_fmu(what.law_fmu)[0] != "native":
        return

    def build():
        from descent_fmus.synthesis.fmi.native.builders.law_fmu import interpreter_fmu
        try:
            interpreter_fmu()
        except Exception:          # the export builds it again and reports what failed
            pass
    threading.Thread(target=build, name="interpreter-fmu", daemon=True).start()


def _archive_laws(checkpoint: dict) -> list:
    """The laws of a checkpoint's Pareto archive (for :mod:`synthesis.run.readable_ahead`)."""
    from descent_fmus.synthesis.run.loop import load_archive
    return [c.law for c, _, _ in load_archive(checkpoint["archive"]).items]


def run_synthesize(args) -> int:
    from descent_fmus.synthesis.methods.registry import UnknownMethodError, entry_of
    from descent_fmus.synthesis.paths import FMUNotFoundError
    from descent_fmus.synthesis.run.evaluation import SchedulerError, SystematicFailure
    from descent_fmus.synthesis.run.loop import RunDirError, run_synthesis
    from descent_fmus.synthesis.run.resources import ResourceLimitError

    problem = apply_options(load_problem(args), args)
    try:
        entry = entry_of(args.method, problem)
    except UnknownMethodError as exc:
        raise CliError(str(exc)) from None
    if entry.needs_flights and problem.budget.flights < 1:
        raise CliError(f"method {args.method} needs a flight budget: give --flights N")
    export = _law_export(args)
    from descent_fmus.synthesis.run import readable_ahead
    readable_ahead.start(args.out, _archive_laws)   # forked before any thread starts
    _warm_interpreter(export)
    try:
        summary = run_synthesis(problem, args.out, fmu_folder(args), method=args.method,
                                workers=args.workers, scheduler=args.scheduler,
                                resume=args.resume, progress=not (args.quiet or args.json),
                                export=export, reference=not args.no_reference)
    except (RunDirError, SchedulerError, FMUNotFoundError, SystematicFailure,
            ResourceLimitError) as exc:
        raise CliError(str(exc)) from None
    finally:
        readable_ahead.stop()
    emit(args, {k: v for k, v in summary.items() if k != "pareto"},
         "\n".join(_summary_lines(problem, args, summary)))
    return 0


def _summary_lines(problem, args, summary) -> list:
    lines = [f"synthesis of {problem.name} ({args.method}): {summary['generations']} "
             f"generations, {summary['simulated']} closed-loop simulations in "
             f"{summary['seconds']:.0f} s ({summary['evaluations_per_second']:.0f}/s, "
             f"{summary['failures']} failed), {summary['pareto_size']} Pareto laws",
             f"  results in {args.out}: pareto.csv, pareto.json, pareto.png, summary.json"
             + (", laws/<k>/" if not args.no_export else "")]
    if summary.get("ended_because"):       # which limit ended the run, and what was left
        hint = (" (a larger --generations uses them)"
                if summary["ended_by"] == "generations" and summary.get("flights_left")
                else "")
        lines.append(f"  ended: {summary['ended_because']}{hint}")
    if summary.get("first_failure"):       # failed candidates were penalised: the first reason
        lines.append(f"  first failed evaluation: {summary['first_failure']}")
    feas = summary.get("feasibility")
    if feas:
        lines.append(f"  constraints: {feas['infeasible']} of {feas['evaluated']} evaluated "
                     f"laws infeasible")
        if "best_infeasible" in feas and not any(r.get("feasible") for r in
                                                 summary.get("pareto", [])):
            lines.append(f"  no feasible law; the best infeasible one: "
                         f"{feas['best_infeasible']['constraints']}")
    st = summary.get("structure")
    if st:
        lines.append("  structure: the best law " + (
            "keeps the basic law's form (the search tuned its parameters)"
            if st["best_law_keeps_basic_form"] else
            f"changes {st['best_law_matrix_changes']} entries of the basic law's matrix")
            + f"; {st['pareto_laws_with_new_form']} Pareto laws have a new form")
        if st.get("best_law_q_at_range_edge"):
            lo, hi = st["q_range"]
            qs = ", ".join(f"q{i}" for i in st["best_law_q_at_range_edge"])
            lines.append(f"  warning: the best law's parameters {qs}"
                         f" sit at the edge of the parameters' range [{lo:g}, {hi:g}): the "
                         f"search was stopped there; widen the range ([ga] q_range)")
    if summary.get("law_fmu_note"):
        lines.append(f"  note: {summary['law_fmu_note']}")
    return lines + problem.report.lines(summary)
