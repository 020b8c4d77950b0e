"""Command line of descent-fmus.

One pattern: general commands act on any problem, system commands are
``descent-fmus <system> <action>``::

    descent-fmus synthesize NAME | --problem FILE.toml --out DIR   synthesis of a feedback law
    descent-fmus build-plant FILE.py [-d DIR]                      a plant: pythonfmu + native twin
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

from descent_fmus.synthesis.cli.common import CliError, OneLineParser, add_common_options, emit

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    from descent_fmus.synthesis.registry import all_systems
    ap = OneLineParser(prog="descent-fmus", description=__doc__.splitlines()[0],
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog="\n".join(__doc__.splitlines()[2:]))
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND",
                            parser_class=OneLineParser)
    from descent_fmus.synthesis.cli.synthesize import add_synthesize_command
    add_synthesize_command(sub)
    from descent_fmus.synthesis.cli.export_law import add_export_law_command
    add_export_law_command(sub)
    from descent_fmus.synthesis.cli.build_plant import add_build_plant_command
    add_build_plant_command(sub)
    from descent_fmus.synthesis.cli.fmi3_variant import add_fmi3_variant_command
    add_fmi3_variant_command(sub)
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


# -- listings ---------------------------------------------------------------------------------------
def run_problems(args) -> int:
    from descent_fmus.synthesis.methods.registry import method_names
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
                             "constraints": [c.name for c in pb.constraints],
                             "initial_states": len(pb.initial_states),
                             "methods": method_names(pb),
                             "options": [o.name for o in pb.options]})
    lines = ["synthesis problems (descent-fmus synthesize NAME; any plant FMU: --problem "
             "FILE.toml):"]
    for p in problems:
        lines.append(f"  {p['problem']:16s} {p['description']}")
        extra = ", ".join(p["methods"]) + (f"; options: {', '.join(p['options'])}"
                                           if p["options"] else "")
        lines.append(f"  {'':16s}   methods: {extra}")
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


def main(argv=None, last_words: list | None = None) -> int:
    """Run the command of ``argv`` (default: the process's); its exit code.  A stopped run's
    one-line report goes to ``last_words`` if given (the program prints it last), else to
    stderr."""
    # The command line chooses the matplotlib backend (files only); library code never does.
    os.environ.setdefault("MPLBACKEND", "Agg")
    from descent_fmus.models.controllers.law_interpreter import MatrixError
    from descent_fmus.models.params import ParameterError
    from descent_fmus.synthesis.fmi.slave import FMUError
    from descent_fmus.synthesis.run.signals import RunInterrupted, as_stop

    import faulthandler
    if not faulthandler.is_enabled():
        # a crash inside an FMU's native code prints the Python stack it happened in
        faulthandler.enable()
    ap = build_parser()
    args = ap.parse_args(argv)
    name = args.command + (f" {args.action}" if getattr(args, "action", None) else "")
    try:
        try:
            return int(args.func(args) or 0)
        except Exception as exc:
            # a stop that landed inside a C extension's import comes out as its ImportError
            stop = as_stop(exc)
            if stop is not None and stop is not exc:
                raise stop from None
            raise
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
        program = launched_as() if argv is None else "descent-fmus"
        argv = list(sys.argv[1:] if argv is None else argv)
        how = (f" -- continue with: {program} " + shlex.join(
            argv + ([] if "--resume" in argv else ["--resume"])))
        line = f"descent-fmus {name}: {exc}" + (how if getattr(exc, "resumable", False) else "")
        if last_words is not None:
            last_words.append(line)          # printed after the exit handlers (entry)
        else:
            print(line, file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"descent-fmus {name}: interrupted", file=sys.stderr)
        return 130


def launched_as() -> str:
    """The program as the user launched it, for a hint that repeats the command: ``python -m
    descent_fmus.synthesis.cli.main`` as typed; the script's name where the shell finds that
    same script on the PATH (``descent-fmus``); else its path as typed
    (``.venv/bin/descent-fmus``)."""
    import shutil
    args = sys.argv[1:]
    orig = list(getattr(sys, "orig_argv", None) or [])
    prefix = orig[:len(orig) - len(args)] if args and orig[-len(args):] == args else []
    if len(prefix) >= 3 and prefix[-2] == "-m":
        return shlex.join(prefix)
    script = sys.argv[0] or "descent-fmus"
    name = os.path.basename(script)
    found = shutil.which(name)
    try:
        if found and os.path.samefile(found, script):
            return name
    except OSError:
        pass
    return shlex.quote(script)


def entry() -> None:
    """The ``descent-fmus`` program: :func:`main`, then the process ends right after its exit
    handlers have run.

    The exit handlers free the FMUs loaded in this process and remove their folders, and every
    result is written by then.  The interpreter's own teardown is skipped: with pythonfmu FMUs
    loaded in the process (``--workers 1``) it was seen, rarely, to abort in glibc's heap checks
    ("corrupted double-linked list") after a run had finished and written everything -- an
    exit status that would have reported a good run as a crash.
    """
    last_words: list = []
    _first_word(sys.argv[1:])
    try:
        code = main(last_words=last_words)
    except SystemExit as exc:          # argparse: --help, usage errors
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        if exc.code is not None and not isinstance(exc.code, int):
            print(exc.code, file=sys.stderr)
    # a stopped run's one line comes last, after whatever a library's exit handler prints
    # (a Dask cluster stopped while it started reports its state there)
    exit_without_teardown(code, last_words)


def _first_word(argv) -> None:
    """A synthesis on a terminal says it started before its imports and checks (a second or
    more on a busy machine): progress within a second of the command."""
    quiet = {"--quiet", "--json", "--help", "-h"}
    if argv[:1] == ["synthesize"] and not quiet & set(argv) and sys.stderr.isatty():
        print("descent-fmus synthesize: starting", file=sys.stderr, flush=True)


def exit_without_teardown(code, last_words=()) -> None:
    """End the process with ``code`` once the exit handlers have run and the output is
    flushed, skipping the interpreter's teardown (see :func:`entry`: with pythonfmu FMUs loaded
    in the process, glibc's heap checks were seen, rarely, to abort it after all work was
    done).  The test session ends the same way (``tests/conftest.py``)."""
    import atexit
    atexit._run_exitfuncs()
    for line in last_words:
        print(line, file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(code or 0))


if __name__ == "__main__":
    entry()
