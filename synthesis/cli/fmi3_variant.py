"""``descent-fmus fmi3-variant NATIVE.fmu --out FILE.fmu``: the FMI 3.0 variant of a native FMU.

Any native FMI 2.0 FMU of the package -- a plant or controller of ``fmus/native/``, an exported
law, the native twin ``descent-fmus build-plant`` wrote of a user's plant -- compiled again
from its own sources with the FMI 3.0 wrapper
(:func:`synthesis.fmi.native.builders.fmi3.fmi3_variant`), or a closed loop of the package's
engine (``fmus/*ClosedLoop.fmu``, ``fmus/native/*ClosedLoop.fmu``, a law export's), the engine
under the same wrapper (:func:`synthesis.fmi.loop_fmi3.loop_variant`)::

    descent-fmus build-plant my_plant.py -d build
    descent-fmus fmi3-variant build/native/MyPlant.fmu --out MyPlant3.fmu
    fmpy simulate MyPlant3.fmu
    descent-fmus fmi3-variant fmus/native/ReentryClosedLoop.fmu --out Loop3.fmu
"""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.cli.common import CliError, add_common_options, emit

__all__ = ["add_fmi3_variant_command"]


def add_fmi3_variant_command(sub) -> None:
    p = sub.add_parser("fmi3-variant", help="the FMI 3.0 variant of a native FMU or closed "
                       "loop (the same C model or engine, compiled with the FMI 3.0 wrapper)")
    p.add_argument("fmu", type=Path, metavar="NATIVE.fmu", help="a native FMI 2.0 FMU of "
                   "descent-fmus (fmus/native/<Name>.fmu, an exported law, build-plant's twin) "
                   "or a closed loop of its engine (<Name>ClosedLoop.fmu)")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.fmu",
                   help="the FMI 3.0 FMU (an existing file is not overwritten)")
    add_common_options(p, fmus=False)
    p.set_defaults(func=run_fmi3_variant)


def run_fmi3_variant(args) -> int:
    import zipfile

    from descent_fmus.synthesis.fmi.native.builders.build import (CompilerNotFoundError,
                                                                  NativeBuildError)
    from descent_fmus.synthesis.fmi.loop_fmi3 import any_fmi3_variant
    from descent_fmus.synthesis.fmi.native.builders.fmi3 import NotNativeError
    if args.out.exists():
        raise CliError(f"{args.out} exists; choose another --out (nothing was overwritten)")
    if not args.fmu.is_file():
        raise CliError(f"{args.fmu}: no such file")
    try:
        out = any_fmi3_variant(args.fmu, args.out)
    except (NotNativeError, CompilerNotFoundError, NativeBuildError) as exc:
        raise CliError(str(exc).splitlines()[0]) from None
    except zipfile.BadZipFile:
        raise CliError(f"{args.fmu} is not an FMU (not a zip file)") from None
    emit(args, {"fmu": str(args.fmu), "out": str(out), "fmi_version": "3.0"},
         f"wrote {out} (FMI 3.0)\n  fmpy simulate {out}")
    return 0
