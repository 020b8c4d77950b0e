"""``descent-fmus export-law LAW.json --out DIR``: a law file as a native C FMU (no Python in the
host) or a pythonfmu FMU, with its readable form and ``law.h``/``law.c``
(:func:`synthesis.fmi.law_files.export_law_files`); the native FMU is the network-operator
interpreter with the law's start values, or with ``--compiled`` the law's own C compiled;
``--closed-loop`` adds the closed loop of the law's problem and its SSP file; ``--fmi3`` adds
the FMI 3.0 variant of the native law FMU (``fmi3/<ID>.fmu``)."""
from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from descent_fmus.synthesis.cli.common import CliError, add_common_options, emit, fmu_folder
from descent_fmus.synthesis.fmi.law_files import choose_law_fmu, export_law_files

__all__ = ["add_export_law_command", "run_export_law"]


def add_export_law_command(sub) -> None:
    """``descent-fmus export-law LAW.json --native|--python --out DIR``."""
    p = sub.add_parser("export-law", help="a law file as a native FMU (C, no Python in the host) "
                       "or a pythonfmu FMU, with its readable form and law.h/law.c")
    p.add_argument("law", type=Path, metavar="LAW.json", help="a law file (law.json of a "
                   "synthesis run, or any NetworkOperator.save)")
    kind = p.add_mutually_exclusive_group()
    kind.add_argument("--native", dest="law_fmu", action="store_const", const="native",
                      help="native C FMU: the network-operator interpreter with the law's start "
                           "values (default where a C compiler exists)")
    kind.add_argument("--python", dest="law_fmu", action="store_const", const="python",
                      help="the pythonfmu NetworkOperatorController with the law as defaults")
    p.add_argument("--compiled", action="store_true",
                   help="a native FMU compiled from the law's own C (law.c inside it; the same "
                        "flights as the interpreter FMU)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="output folder (must not exist or be empty: nothing is overwritten)")
    p.add_argument("--name", default=None, metavar="ID",
                   help="model identifier of the native FMU and prefix of the C names "
                        "(default NetworkOperatorLaw)")
    p.add_argument("--closed-loop", action="store_true",
                   help="also the closed-loop FMU and SSP of the law's problem (plant FMU + "
                        "this law FMU)")
    p.add_argument("--fmi3", action="store_true",
                   help="also the FMI 3.0 variant of the native law FMU, fmi3/<ID>.fmu (the "
                        "FMI 2.0 one stays: closed loops and SSP files take FMI 2.0)")
    p.add_argument("--problem", default=None, metavar="NAME",
                   help="the law's registered problem (default: the 'problem' field of the law "
                        "file); or --problem-file")
    p.add_argument("--problem-file", type=Path, default=None, metavar="FILE.toml",
                   help="the law's problem as a problem file")
    add_common_options(p)
    p.set_defaults(func=run_export_law, law_fmu=None)


def _problem_of(args, doc: dict):
    from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file
    from descent_fmus.synthesis.registry import UnknownProblemError, get_problem
    if args.problem_file is not None:
        try:
            return load_problem_file(args.problem_file, fmu_dir=fmu_folder(args))
        except ProblemFileError as exc:
            raise CliError(str(exc)) from None
    name = args.problem or doc.get("problem")
    if name is None:
        if args.closed_loop:
            raise CliError(f"{args.law} names no problem: give --problem NAME or "
                           f"--problem-file FILE for --closed-loop")
        return None
    try:
        return get_problem(name)
    except UnknownProblemError as exc:
        raise CliError(str(exc)) from None


def _fmi3_law(files: dict, folder: Path) -> str:
    """The FMI 3.0 variant of the exported native law FMU, ``<folder>/fmi3/<ID>.fmu``."""
    from descent_fmus.synthesis.fmi.native.builders.fmi3 import fmi3_variant
    if files["law_fmu"] != "native":
        raise CliError(f"--fmi3 needs the native law FMU, but this law is exported as a "
                       f"pythonfmu FMU ({files['note'] or 'asked with --python'}); pythonfmu "
                       f"FMUs are FMI 2.0 only")
    ctrl = Path(files["controller_fmu"])
    return str(fmi3_variant(ctrl, folder / "fmi3" / ctrl.name))


def run_export_law(args) -> int:
    from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
    from descent_fmus.synthesis.fmi.native.builders.build import (CompilerNotFoundError,
                                                                  NativeBuildError)
    from descent_fmus.synthesis.paths import FMUNotFoundError

    out = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise CliError(f"{out} exists and is not an empty folder; choose another --out "
                       f"(nothing was overwritten)")
    try:
        doc = json.loads(args.law.read_text())
    except (OSError, json.JSONDecodeError):
        doc = {}
    try:
        law = NetworkOperator.load(args.law)
    except (LawFileError, OSError) as exc:
        raise CliError(f"{args.law}: {exc}") from None
    problem = _problem_of(args, doc if isinstance(doc, dict) else {})
    if args.compiled and args.law_fmu == "python":
        raise CliError("--compiled is a native FMU: drop --python")
    try:
        kind, note = choose_law_fmu("native" if args.compiled else args.law_fmu or "auto")
    except CompilerNotFoundError as exc:
        raise CliError(str(exc)) from None
    if note:
        print(f"descent-fmus export-law: {note}", file=sys.stderr)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        files = export_law_files(law, tmp, law_fmu=kind, fmu_dir=fmu_folder(args),
                                 identifier=args.name, problem=problem,
                                 closed_loop=args.closed_loop,
                                 description=f"law {args.law.name}",
                                 extra={"problem": problem.name} if problem else None,
                                 compiled=args.compiled)
        if args.fmi3:
            files["controller_fmu_fmi3"] = _fmi3_law(files, tmp)
        if out.exists():
            out.rmdir()                 # empty (checked above)
        mask = os.umask(0)
        os.umask(mask)
        tmp.chmod(0o777 & ~mask)        # mkdtemp's folder is private
        tmp.rename(out)
    except (NativeBuildError, FMUNotFoundError, ValueError) as exc:
        raise CliError(str(exc)) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    paths = {k: str(out / Path(v).relative_to(tmp)) for k, v in files.items()
             if k not in ("law_fmu", "note", "closed_loop_plant")}
    r = law.readable()
    summary = dict(paths, law_fmu=kind, note=note, readable=r.to_dict(), out=str(out))
    if "closed_loop_plant" in files:
        summary["closed_loop_plant"] = files["closed_loop_plant"]
    lines = [f"law ({kind} FMU) in {out}:"] + [f"  {line}" for line in r.lines()]
    lines.append(f"  files: {', '.join(sorted(Path(v).name for v in paths.values()))}")
    emit(args, summary, "\n".join(lines))
    return 0
