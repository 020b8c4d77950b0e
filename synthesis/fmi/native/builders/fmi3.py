"""FMI 3.0 variants of the native FMUs: the same C model, the FMI 3.0 wrapper ``fmi3_cs.c``.

A native FMU is written once as FMI 2.0 (:func:`.build.build_fmu`); its FMI 3.0 variant is the
same model compiled with ``c/fmi3/fmi3_cs.c`` (an adapter over the FMI 2.0 wrapper: one state
machine, one set of messages) and described in FMI 3.0 terms from the same variable table
(:func:`.build.fmi3_rows`, :mod:`synthesis.fmi.description.fmi3`).  ``build_fmu(...,
fmi_version=3)`` writes one from the table; :func:`fmi3_variant` writes the variant of a built
FMI 2.0 native FMU -- its variable table read back from its model description, its model's
sources from ``sources/`` -- so every native FMU, whoever built it (a system's twin, an
exported law, a user's plant), has one without its builder knowing.  ``build_fmus.py`` writes
``fmus/native/fmi3/<Name>.fmu`` for every native plant, controller and closed loop
(:func:`build_fmi3_variants`).

A closed loop of the package's engine (:func:`.containers.into_engine`) gets its FMI 3.0
variant the same way (:func:`loop_variant`): the engine compiled under the same FMI 3.0 wrapper
(``c/fmi3/fmi3_loop.c``), the FMI 3.0 description written by the same writer from the closed
loop's FMI 2.0 one, and its ``resources/`` (the FMI 2.0 components, ``loop.txt``) carried over:
the engine still loads FMI 2.0 components, only its own face is FMI 3.0.
"""
from __future__ import annotations

import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from descent_fmus.synthesis.fmi.native.builders.build import (KINDS, WRAPPER_FILES, Variable,
                                                              platform_folder, platform_tuple,
                                                              write_native_fmu)

__all__ = ["NotNativeError", "fmi3_variant", "build_fmi3_variants", "variables_of", "is_native",
           "is_closed_loop", "loop_variant"]


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
    """Write the FMI 3.0 variant of the native FMI 2.0 FMU ``src`` (or closed loop of the
    package's engine: :func:`loop_variant`) to ``dest``.

    Raises
    ------
    NotNativeError
        ``src`` is neither (a pythonfmu FMU, fmpy's container, an FMI 3.0 FMU).
    CompilerNotFoundError, NativeBuildError
    """
    src = Path(src)
    if is_closed_loop(src):
        return loop_variant(src, dest, compiler)
    with zipfile.ZipFile(src) as z:
        names = set(z.namelist())
        if not is_native(src):
            raise NotNativeError(f"{src.name} is not a native FMI 2.0 FMU of descent-fmus nor "
                                 f"a closed loop of its engine: only those have an FMI 3.0 "
                                 f"variant")
        md = ET.fromstring(z.read("modelDescription.xml"))
        files = {n[len("sources/"):]: z.read(n) for n in names
                 if n.startswith("sources/") and not n.endswith("/")
                 and n[len("sources/"):] not in WRAPPER_FILES}
    cs = md.find("CoSimulation")
    model_c = [f.get("name") for f in cs.iter("File") if f.get("name") != "fmi2_cs.c"]
    exp = md.find("DefaultExperiment")
    experiment = {k: float(v) for k, v in exp.attrib.items()} if exp is not None else None
    return write_native_fmu(dest, cs.get("modelIdentifier"), md.get("guid"),
                            md.get("description", ""), variables_of(md), files, [], model_c,
                            experiment, compiler, fmi_version=3)


def is_native(fmu) -> bool:
    """Whether ``fmu`` is a native FMI 2.0 FMU of this package: its sources are the FMI 2.0
    wrapper's and a model's (an FMI 3.0 variant ships ``fmi2_cs.c`` too), and it carries no
    resources (a closed loop carries its components: :func:`is_closed_loop`)."""
    with zipfile.ZipFile(fmu) as z:
        names = z.namelist()
    return ("sources/fmi2_cs.c" in names and "sources/fmi3_cs.c" not in names
            and not any(n.startswith("resources/") for n in names))


def is_closed_loop(fmu) -> bool:
    """Whether ``fmu`` is an FMI 2.0 closed loop of the package's engine: fmpy's container
    archive with the engine as its binary (model identifier ``closed_loop``) and
    ``resources/loop.txt``."""
    with zipfile.ZipFile(fmu) as z:
        if "resources/loop.txt" not in z.namelist():
            return False
        md = ET.fromstring(z.read("modelDescription.xml"))
    cs = md.find("CoSimulation")
    return (md.get("fmiVersion") == "2.0" and cs is not None
            and cs.get("modelIdentifier") == "closed_loop")


def _loop_rows(md: ET.Element) -> tuple:
    """The FMI 3.0 rows of a closed loop's FMI 2.0 description and its time's value
    reference."""
    from descent_fmus.synthesis.fmi.description.fmi3 import Row
    rows, time_vr = [], None
    for sv in md.iter("ScalarVariable"):
        typ, causality, name = sv[0].tag, sv.get("causality"), sv.get("name")
        if causality == "independent":
            time_vr = int(sv.get("valueReference"))
            continue
        start = sv[0].get("start")
        if typ not in ("Real", "Integer") or causality not in ("parameter", "output") or (
                causality == "parameter" and start is None):
            raise NotNativeError(f"variable {name!r} ({causality}, {typ}"
                                 f"{', no start' if start is None else ''}) of the closed loop "
                                 f"has no FMI 3.0 form (Real and Integer parameters with a "
                                 f"start value, outputs)")
        if start is not None:
            start = float(start) if typ == "Real" else int(start)
        rows.append(Row(name, int(sv.get("valueReference")), causality, sv.get("variability"),
                        typ, start, sv.get("description", "")))
    return rows, time_vr


def loop_variant(src, dest, compiler: str | None = None) -> Path:
    """Write the FMI 3.0 variant of the closed loop ``src`` (:func:`is_closed_loop`) to
    ``dest``: the engine's FMI 3.0 binary, the FMI 3.0 description of the same variables
    (value references, start values, units; ``time`` keeps its value reference 0), every other
    entry (``resources/``: the FMI 2.0 components, ``loop.txt``) as it is.

    Raises
    ------
    NotNativeError
        ``src`` is not such a closed loop, or has a variable of no FMI 3.0 form here.
    CompilerNotFoundError, NativeBuildError
    """
    from descent_fmus.synthesis.fmi.compose import rewrite_archive
    from descent_fmus.synthesis.fmi.containers import engine_library
    from descent_fmus.synthesis.fmi.description.fmi3 import model_description
    src, dest = Path(src), Path(dest)
    if not is_closed_loop(src):
        raise NotNativeError(f"{src.name} is not a closed loop of the descent-fmus engine")
    with zipfile.ZipFile(src) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    rows, time_vr = _loop_rows(md)
    exp = md.find("DefaultExperiment")
    xml = model_description("closed_loop", md.get("guid"), md.get("description", ""), rows,
                            {k: float(v) for k, v in exp.attrib.items()} if exp is not None
                            else None, "descent-fmus (closed-loop engine, FMI 3.0)", time_vr,
                            md.get("modelName"))
    lib = engine_library(3, compiler).read_bytes()
    binary = f"binaries/{platform_tuple()}/closed_loop{platform_folder()[1]}"
    dest.parent.mkdir(parents=True, exist_ok=True)

    def edit(item, data):
        if item.filename.startswith("binaries/"):
            return []
        return [(item, xml if item.filename == "modelDescription.xml" else data)]
    return rewrite_archive(src, dest, edit, extra=[(binary, lib)])


def build_fmi3_variants(fmus, out_dir, compiler: str | None = None, say=print) -> list:
    """The FMI 3.0 variant of every native FMU and closed loop of the engine among ``fmus``
    into ``out_dir``, under the same file names; ``say`` gets one line per FMU."""
    built = []
    for fmu in map(Path, fmus):
        if fmu.suffix == ".fmu" and (is_native(fmu) or is_closed_loop(fmu)):
            t0 = time.perf_counter()
            built.append(fmi3_variant(fmu, Path(out_dir) / fmu.name, compiler))
            say(f"built {Path(out_dir).name}/{fmu.name}, FMI 3.0 "
                f"({time.perf_counter() - t0:.1f} s)")
    return built
