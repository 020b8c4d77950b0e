"""FMI 3.0 variants of the closed-loop FMUs: the package's engine under the FMI 3.0 wrapper.

A closed loop of the engine (:func:`.containers.into_engine`: fmpy's container archive, the
engine ``closed_loop.c`` as its binary, the two FMI 2.0 components and ``loop.txt`` in
``resources/``) gets its FMI 3.0 variant (:func:`loop_variant`) the way a native FMU does
(:mod:`synthesis.fmi.native.builders.fmi3`): the engine compiled under the same FMI 3.0 wrapper
(``c/fmi3/fmi3_loop.c``: ``fmi3_cs.c`` over ``closed_loop.c`` and ``loop_values.c``), the FMI 3.0
model description written by the same writer (:mod:`synthesis.fmi.description.fmi3`) from the
closed loop's FMI 2.0 one, and ``resources/`` carried over as it is.  The engine still loads FMI
2.0 components; only its own face is FMI 3.0.  ``build_fmus.py`` writes
``fmus/native/fmi3/<Name>ClosedLoop.fmu`` for every native closed loop
(:func:`build_loop_variants`); :func:`any_fmi3_variant` makes the variant of a native FMU or a
closed loop alike (``descent-fmus fmi3-variant``).
"""
from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from descent_fmus.synthesis.fmi.native.builders.fmi3 import (NotNativeError, build_fmi3_variants,
                                                              fmi3_variant, is_native)

__all__ = ["is_closed_loop", "loop_variant", "any_fmi3_variant", "build_loop_variants"]

#: generationTool of a closed loop's FMI 3.0 variant
GENERATION_TOOL = "descent-fmus (closed-loop engine, FMI 3.0)"


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


def _rows(md: ET.Element) -> tuple:
    """The FMI 3.0 rows of a closed loop's FMI 2.0 description, and its time's value
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
                                 f"has no FMI 3.0 form here (Real and Integer parameters with "
                                 f"a start value, outputs)")
        if start is not None:
            start = float(start) if typ == "Real" else int(start)
        rows.append(Row(name, int(sv.get("valueReference")), causality, sv.get("variability"),
                        typ, start, sv.get("description", "")))
    return rows, time_vr


def loop_variant(src, dest, compiler: str | None = None) -> Path:
    """Write the FMI 3.0 variant of the closed loop ``src`` (:func:`is_closed_loop`) to
    ``dest``: the engine's FMI 3.0 binary, the FMI 3.0 description of the same variables
    (names, value references, start values, units; ``time`` keeps its value reference 0),
    every other entry (``resources/``: the FMI 2.0 components, ``loop.txt``) as it is.

    Raises
    ------
    NotNativeError
        ``src`` is no such closed loop, or has a variable of no FMI 3.0 form here.
    CompilerNotFoundError, NativeBuildError
    """
    from descent_fmus.synthesis.fmi.compose import rewrite_archive
    from descent_fmus.synthesis.fmi.containers import engine_library
    from descent_fmus.synthesis.fmi.description.fmi3 import model_description
    from descent_fmus.synthesis.fmi.native.builders.build import platform_folder, platform_tuple
    src, dest = Path(src), Path(dest)
    if not is_closed_loop(src):
        raise NotNativeError(f"{src.name} is not a closed loop of the descent-fmus engine")
    with zipfile.ZipFile(src) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    rows, time_vr = _rows(md)
    exp = md.find("DefaultExperiment")
    experiment = {k: float(v) for k, v in exp.attrib.items()} if exp is not None else None
    xml = model_description("closed_loop", md.get("guid"), md.get("description", ""), rows,
                            experiment, GENERATION_TOOL, time_vr, md.get("modelName"))
    lib = engine_library(3, compiler).read_bytes()
    binary = f"binaries/{platform_tuple()}/closed_loop{platform_folder()[1]}"
    dest.parent.mkdir(parents=True, exist_ok=True)

    def edit(item, data):
        if item.filename.startswith("binaries/"):
            return []
        return [(item, xml if item.filename == "modelDescription.xml" else data)]
    return rewrite_archive(src, dest, edit, extra=[(binary, lib)])


def any_fmi3_variant(src, dest, compiler: str | None = None) -> Path:
    """The FMI 3.0 variant of ``src``, a closed loop of the engine (:func:`loop_variant`) or a
    native FMU (:func:`.builders.fmi3.fmi3_variant`), written to ``dest``.

    Raises
    ------
    NotNativeError
        ``src`` is neither (a pythonfmu FMU, fmpy's container, an FMI 3.0 FMU).
    CompilerNotFoundError, NativeBuildError
    """
    if is_closed_loop(src):
        return loop_variant(src, dest, compiler)
    if not is_native(src):
        raise NotNativeError(f"{Path(src).name} is not a native FMI 2.0 FMU of descent-fmus "
                             f"nor a closed loop of its engine: only those have an FMI 3.0 "
                             f"variant")
    return fmi3_variant(src, dest, compiler)


def build_loop_variants(fmus, out_dir, compiler: str | None = None, say=print) -> list:
    """The FMI 3.0 variant of every closed loop of the engine among ``fmus`` into ``out_dir``,
    under the same file names; ``say`` gets one line per FMU."""
    return build_fmi3_variants(fmus, out_dir, compiler, say, accept=is_closed_loop,
                               variant=loop_variant)
