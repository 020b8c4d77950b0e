"""FMI 3.0 variants of the native FMUs: the same C model, the FMI 3.0 wrapper ``fmi3_cs.c``.

A native FMU is written once as FMI 2.0 (:func:`.build.build_fmu`); its FMI 3.0 variant is the
same model compiled with ``c/fmi3/fmi3_cs.c`` (an adapter over the FMI 2.0 wrapper: one state
machine, one set of messages) and described in FMI 3.0 terms from the same variable table
(:func:`.build.fmi3_rows`, :mod:`synthesis.fmi.description.fmi3`).  ``build_fmu(...,
fmi_version=3)`` writes one from the table; :func:`fmi3_variant` writes the variant of a built
FMI 2.0 native FMU -- its variable table read back from its model description, its model's
sources from ``sources/`` -- so every native FMU, whoever built it (a system's twin, an
exported law, a user's plant), has one without its builder knowing.  ``build_fmus.py`` writes
``fmus/native/fmi3/<Name>.fmu`` for every native plant and controller
(:func:`build_fmi3_variants`); an interpreter law's ``resources/start_values.txt`` goes with it.

The closed loops' variants are :mod:`synthesis.fmi.loop_fmi3`'s (the closed-loop engine under
the same FMI 3.0 wrapper).
"""
from __future__ import annotations

import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from descent_fmus.synthesis.fmi.native.builders.build import (KINDS, WRAPPER_FILES, Variable,
                                                              write_native_fmu)

__all__ = ["NotNativeError", "fmi3_variant", "build_fmi3_variants", "variables_of", "is_native"]


class NotNativeError(ValueError):
    """The FMU is not a native FMI 2.0 FMU of this package (not built by
    :func:`.build.build_fmu` as FMI 2.0)."""


_KIND_OF = {(c, v): kind for kind, (c, v, _) in KINDS.items()}


def variables_of(md: ET.Element) -> list:
    """The variable table of a native FMI 2.0 model description (the inverse of its writer)."""
    out = []
    for sv in md.iter("ScalarVariable"):
        typ = sv[0].tag
        causality, variability = sv.get("causality"), sv.get("variability")
        kind = _KIND_OF.get((causality, "continuous" if causality in ("input", "output")
                             else variability))
        if kind is None or typ not in ("Real", "Integer"):
            raise NotNativeError(f"variable {sv.get('name')!r} ({causality}, {variability}, "
                                 f"{typ}) is not one a native FMU has")
        start = sv[0].get("start", "0")
        out.append(Variable(sv.get("name"), kind,
                            float(start) if typ == "Real" else int(start),
                            sv.get("description", ""), typ))
    return out


def fmi3_variant(src, dest, compiler: str | None = None) -> Path:
    """Write the FMI 3.0 variant of the native FMI 2.0 FMU ``src`` to ``dest``.

    Raises
    ------
    NotNativeError
        ``src`` is not a native FMU of this package (a pythonfmu FMU, a container).
    CompilerNotFoundError, NativeBuildError
    """
    src = Path(src)
    with zipfile.ZipFile(src) as z:
        names = set(z.namelist())
        if not is_native(src):
            raise NotNativeError(f"{src.name} is not a native FMI 2.0 FMU of descent-fmus: only "
                                 f"those have an FMI 3.0 variant")
        md = ET.fromstring(z.read("modelDescription.xml"))
        files = {n[len("sources/"):]: z.read(n) for n in names
                 if n.startswith("sources/") and not n.endswith("/")
                 and n[len("sources/"):] not in WRAPPER_FILES}
        starts = {_STARTS: z.read(f"resources/{_STARTS}")} if f"resources/{_STARTS}" in names \
            else None
    cs = md.find("CoSimulation")
    model_c = [f.get("name") for f in cs.iter("File") if f.get("name") != "fmi2_cs.c"]
    exp = md.find("DefaultExperiment")
    experiment = {k: float(v) for k, v in exp.attrib.items()} if exp is not None else None
    return write_native_fmu(dest, cs.get("modelIdentifier"), md.get("guid"),
                            md.get("description", ""), variables_of(md), files, [], model_c,
                            experiment, compiler, fmi_version=3, resources=starts)


#: The one resource a native FMU may carry: an interpreter law's start values (:mod:`.law_fmu`),
#: which the wrapper reads in place of the compiled ones.
_STARTS = "start_values.txt"


def is_native(fmu) -> bool:
    """Whether ``fmu`` is a native FMI 2.0 FMU of this package: its sources are the FMI 2.0
    wrapper's and a model's (an FMI 3.0 variant ships ``fmi2_cs.c`` too), and it carries no
    resources but its start values (a closed loop carries its components:
    :func:`synthesis.fmi.loop_fmi3.is_closed_loop`)."""
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    return ("sources/fmi2_cs.c" in names and "sources/fmi3_cs.c" not in names
            and not any(n.startswith("resources/") and n not in ("resources/",
                                                                  f"resources/{_STARTS}")
                        for n in names))


def build_fmi3_variants(fmus, out_dir, compiler: str | None = None, say=print, *,
                        accept=is_native, variant=fmi3_variant) -> list:
    """The FMI 3.0 variant of every FMU among ``fmus`` that ``accept`` takes (by default the
    native FMUs; closed loops are skipped), made by ``variant(src, dest, compiler)`` into
    ``out_dir``, under the same file names; ``say`` gets one line per FMU."""
    built = []
    for fmu in map(Path, fmus):
        if fmu.suffix == ".fmu" and accept(fmu):
            t0 = time.perf_counter()
            built.append(variant(fmu, Path(out_dir) / fmu.name, compiler))
            say(f"built {Path(out_dir).name}/{fmu.name}, FMI 3.0 "
                f"({time.perf_counter() - t0:.1f} s)")
    return built
