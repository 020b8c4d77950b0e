"""Command line of descent-fmus: ``descent-fmus <command> ...`` (``--help`` lists them).

Each system contributes its sub-commands from a module of ``synthesis.commands`` that defines
``register(subparsers)``; every command accepts ``--json`` for a machine-readable summary.
"""
from __future__ import annotations

import argparse
import importlib
import sys

# defined in synthesis.commands so that 'python -m synthesis.cli' and the installed script
# share one class (a module run as __main__ is loaded twice)
from synthesis.commands import CliError, emit  # noqa: F401

#: Modules that add sub-commands (one line per system).
COMMAND_MODULES = [
    "synthesis.commands.reentry",
    "synthesis.commands.reorient",
    "synthesis.commands.mars",
    "synthesis.commands.land",
    "synthesis.commands.synthesize",
    "synthesis.commands.lunar_descent",
]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="descent-fmus", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return ap


def main(argv=None) -> int:
    from models.controllers.network_operator import MatrixError
    from models.fmu_support import ParameterError
    from synthesis.cosim import FMUError

    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"descent-fmus {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (OSError, FMUError, ParameterError, MatrixError) as exc:
        # user-facing failures (a missing FMU or folder, a file that cannot be written, an FMU
        # rejecting a value): one line, no traceback
        print(f"descent-fmus {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"descent-fmus {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
