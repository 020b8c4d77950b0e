"""Build the pythonfmu FMUs: slaves of the model classes and copies with new defaults.

* :func:`build_slave` -- a pythonfmu FMU from a class of ``models/`` (the modules it needs are
  bundled in the FMU's resources, so the FMU runs on the same equations as in-process code).
* :func:`with_defaults` -- a copy of a built FMU whose start values are replaced (XML and the
  ``resources/defaults.json`` the slave applies on instantiation).  An exported law *is* the generic
  controller FMU with the winner's values as defaults.
* :func:`add_units`, :func:`add_status_wrapper` -- the units of the variables and the FMI 2.0
  status wrapper put into a built FMU.

The closed loops composed of two FMUs (container FMUs, SSP files) are in :mod:`.containers`.
"""
from __future__ import annotations

import functools
import json
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from fmpy import read_model_description

from descent_fmus.synthesis.paths import require_fmu

__all__ = ["build_slave", "build_bundle", "model_imports", "model_closure", "with_defaults",
           "add_units", "add_status_wrapper", "rewrite_archive"]

#: The models package (bundled into every pythonfmu FMU, only the modules the FMU imports).
MODELS = Path(__file__).resolve().parents[2] / "models"
if not (MODELS / "fmu_support.py").is_file():      # installed: the sibling package
    import descent_fmus.models as _models
    MODELS = Path(_models.__file__).parent


def model_imports(path: Path) -> set:
    """Modules of descent_fmus.models that ``path`` imports (names relative to the package)."""
    import ast
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            if name.startswith("descent_fmus.models."):
                rel = name[len("descent_fmus.models."):]
                if (MODELS / (rel.replace(".", "/") + ".py")).is_file():
                    out.add(rel)
    return out


def model_closure(module: str) -> list[str]:
    """``module`` (relative to descent_fmus.models) and every models module it imports."""
    todo, seen = [module], set()
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        path = MODELS / (m.replace(".", "/") + ".py")
        if not path.is_file():
            raise FileNotFoundError(f"no module descent_fmus.models.{m} ({path})")
        seen.add(m)
        todo.extend(model_imports(path) - seen)
    return sorted(seen)


def entry_script(module: str, cls: str) -> str:
    """The FMU's entry module: imports the class and balances pythonfmu 0.7's reference count.

    pythonfmu 0.7 re-executes the entry module's code in the module's namespace every time the
    FMU is instantiated and then releases one reference to that namespace it never took
    (``models.pythonfmu_compat``); the last line takes that reference on every execution.
    ``module``: of descent_fmus.models, or ``"/name"``: a top-level one (a user's plant)."""
    source = module[1:] if module.startswith("/") else f"descent_fmus.models.{module}"
    return (f'"""pythonfmu entry point of the {cls} FMU (written by descent-fmus)."""\n'
            f"from {source} import {cls}  # noqa: F401\n"
            f"from descent_fmus.models.pythonfmu_compat import balance_namespace\n"
            f"balance_namespace(globals())\n")


def build_slave(fmu_class: str, dest_dir: Path) -> Path:
    """Build the pythonfmu FMU of ``"module:Class"`` (module relative to descent_fmus.models).

    The FMU's entry script is a short module importing the class; its resources carry the
    ``descent_fmus/models`` modules the class needs, without ``__init__.py`` files: namespace
    packages, so that in one host process the portions of several of our FMUs merge (each FMU
    finds its modules whichever was loaded first), and an installed descent-fmus keeps its own
    regular packages.
    """
    module, cls = fmu_class.split(":")
    return build_bundle(module, cls, model_closure(module), dest_dir)


def build_bundle(module: str, cls: str, modules, dest_dir: Path, extra=()) -> Path:
    """:func:`build_slave` of ``cls`` of ``module`` (:func:`entry_script`) with the models
    ``modules`` and the ``extra`` files ``(path, name)`` beside the entry."""
    from pythonfmu import FmuBuilder
    with tempfile.TemporaryDirectory(prefix="descent_fmus_") as tmp:
        tmp = Path(tmp)
        pkg = tmp / "descent_fmus"
        for m in modules:
            rel = Path(*m.split(".")).with_suffix(".py")
            (pkg / "models" / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(MODELS / rel, pkg / "models" / rel)
        script = tmp / "entry" / f"{cls}.py"
        script.parent.mkdir()
        script.write_text(entry_script(module, cls))
        for f, name in extra:               # beside the entry: importable when pythonfmu builds
            shutil.copy(f, script.parent / name)
        # the entry imports them by name: a module of that name imported by an earlier build
        # in this process (another file, or this file before an edit) must not stand in
        fresh = [Path(name).stem for _, name in extra if name.endswith(".py")]
        for name in fresh:
            sys.modules.pop(name, None)
        try:
            fmu = Path(FmuBuilder.build_FMU(script, dest=Path(dest_dir), project_files=[pkg] + [
                script.parent / name for _, name in extra]))
        finally:
            for name in fresh:
                sys.modules.pop(name, None)
    return add_status_wrapper(add_units(fmu))


@functools.cache
def _status_library() -> bytes | None:
    """The status wrapper (``synthesis/fmi/native/c/fmi2/pythonfmu_status.c``) compiled for this
    machine (once per process), or None where it cannot be (no C compiler, not linux64)."""
    from descent_fmus.synthesis.fmi.native.builders.build import (NativeBuildError, c_file,
                                                                  compile_sources, find_compiler,
                                                                  platform_folder)
    if platform_folder() != ("linux64", ".so") or find_compiler() is None:
        return None
    try:
        with tempfile.TemporaryDirectory(prefix="descent_status_") as tmp:
            return compile_sources(c_file("pythonfmu_status.c").parent,
                                   ["pythonfmu_status.c"], Path(tmp) / "wrapper.so",
                                   libraries=("dl",)).read_bytes()
    except NativeBuildError:
        return None


def rewrite_archive(src: Path, dst: Path, edit, extra=()) -> Path:
    """Copy the zip archive ``src`` to ``dst`` (atomically; ``dst`` may be ``src``), every
    entry through ``edit(item, data)``, which returns the ``(ZipInfo or name, bytes)`` pairs to
    write in its place (none: the entry is dropped); ``extra`` pairs are appended.  An entry
    whose bytes ``edit`` passes on as they are (the same object) is copied compressed, under
    the pair's name (:mod:`synthesis.fmi.native.builders.archives`); new bytes are deflated."""
    from descent_fmus.synthesis.fmi.native.builders.archives import (copied, deflated,
                                                                     raw_members, write_archive)
    entries = []
    with zipfile.ZipFile(src) as zin:
        for item, raw in raw_members(src):
            data = zin.read(item.filename)
            for info, out in edit(item, data):
                name = info.filename if isinstance(info, zipfile.ZipInfo) else info
                entries.append(copied(name, item, raw) if out is data else
                               deflated(name, _bytes(out)))
    entries += [deflated(info.filename if isinstance(info, zipfile.ZipInfo) else info,
                         _bytes(data)) for info, data in extra]
    return write_archive(dst, entries)


def _bytes(data) -> bytes:
    """A member's content: text as UTF-8 (as zipfile's ``writestr`` takes it)."""
    return data.encode() if isinstance(data, str) else data


def add_status_wrapper(fmu: Path) -> Path:
    """Give a pythonfmu FMU the FMI status of a user error (in place, atomically).

    pythonfmu reports a parameter the FMU rejects in ``fmi2ExitInitializationMode`` as
    fmi2Fatal; FMI 2.0 calls it fmi2Error.  The linux64 binary becomes the status wrapper
    (``synthesis/fmi/native/c/fmi2/pythonfmu_status.c``), which forwards every call to the pythonfmu
    binary, renamed ``<identifier>.pythonfmu.so`` beside it, and reports fmi2Fatal of the
    set-up calls as fmi2Error; it also passes the FMU's errors and warnings to the host's logger
    whatever ``loggingOn`` says (debug messages only when asked).  Without a C compiler the FMU
    is left as pythonfmu built it.
    """
    lib = _status_library()
    if lib is None:
        return fmu
    fmu = Path(fmu)
    with zipfile.ZipFile(fmu) as z:
        ident = ET.fromstring(z.read("modelDescription.xml")).find(
            "CoSimulation").get("modelIdentifier")
        binary = f"binaries/linux64/{ident}.so"
        if binary not in z.namelist():
            return fmu

    def edit(item, data):
        if item.filename != binary:
            return [(item, data)]
        wrapper = zipfile.ZipInfo(binary, date_time=item.date_time)
        wrapper.external_attr, wrapper.compress_type = item.external_attr, zipfile.ZIP_DEFLATED
        item.filename = f"binaries/linux64/{ident}.pythonfmu.so"
        return [(item, data), (wrapper, lib)]
    return rewrite_archive(fmu, fmu, edit)


def _rewrite_model_description(fmu: Path, edit) -> Path:
    """Apply ``edit(root)`` to the modelDescription.xml of ``fmu`` (in place, atomically)."""
    with zipfile.ZipFile(fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    edit(root)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    return rewrite_archive(fmu, fmu, lambda item, data: [
        (item, xml if item.filename == "modelDescription.xml" else data)])


def add_units(fmu: Path) -> Path:
    """Write the units of an FMU's variables into its model description (see
    :func:`units_into_model_description`)."""
    from descent_fmus.synthesis.fmi.description.units import units_into_model_description
    return _rewrite_model_description(Path(fmu), units_into_model_description)


def _start_literal(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    return repr(float(value))


def with_defaults(src_fmu: Path, dst_fmu: Path, values: dict, description: str | None = None
                  ) -> Path:
    """Copy ``src_fmu`` to ``dst_fmu`` with new start values for the named variables.

    The values are written into ``modelDescription.xml`` (what importers show) and into
    ``resources/defaults.json`` (what the slave applies when instantiated), so both agree.
    """
    src_fmu, dst_fmu = require_fmu(src_fmu), Path(dst_fmu)
    md = read_model_description(str(src_fmu))
    known = {v.name: v for v in md.modelVariables}
    unknown = [n for n in values if n not in known]
    if unknown:
        raise KeyError(f"{md.modelName} has no variable(s) {', '.join(unknown)}")
    clean = {}
    for name, value in values.items():
        v = known[name]
        clean[name] = int(value) if v.type == "Integer" else float(value)
    with zipfile.ZipFile(src_fmu) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    for sv in root.iter("ScalarVariable"):
        name = sv.get("name")
        if name in clean:
            sv[0].set("start", _start_literal(clean[name]))
    if description:
        root.set("description", description)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True)

    def edit(item, data):
        if item.filename == "resources/defaults.json":
            return []
        return [(item, xml if item.filename == "modelDescription.xml" else data)]
    dst_fmu.parent.mkdir(parents=True, exist_ok=True)
    return rewrite_archive(src_fmu, dst_fmu, edit,
                            extra=[("resources/defaults.json", json.dumps(clean, indent=1))])
