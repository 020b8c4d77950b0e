"""A user's plant written once -> its pythonfmu FMU and its native C twin, checked bit for bit.

``descent-fmus build-plant my_plant.py`` takes a plant module written in the package's model
style (a ``Params`` dataclass, the right-hand side as plain functions, an ``Integrator``
subclass, the FMU class deriving :class:`models.fmu_support.SlaveBase`), and writes

* ``DIR/<Identifier>.fmu`` -- the pythonfmu FMU (:func:`build_pythonfmu`:
  the module and the ``descent_fmus/models`` modules it imports in its resources);
* ``DIR/native/<Identifier>.fmu`` -- the native twin, C generated from the same class by the
  tracer of the package's own plants (:mod:`.plant_phases`, :func:`.plant_fmu.build_plant_fmu`),

then flies both on short flights (:func:`check_twins`, in a child process) and keeps the twin
only if every output at every communication point is bitwise the pythonfmu FMU's.  A problem
file naming ``DIR/<Identifier>.fmu`` then flies the twin on its own
(:func:`synthesis.fmi.native_loop.native_fmus`).

A construct the tracer cannot follow is a :class:`PlantFileError`: one line naming the file,
the line and the construct.  Nothing is written before the trace has succeeded.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

__all__ = ["PlantFileError", "load_plant_module", "plant_class", "build_plant", "build_pythonfmu",
           "check_twins", "CHECK_STEPS"]

#: Communication steps of each check flight.
CHECK_STEPS = 100


class PlantFileError(Exception):
    """A plant file that cannot be built (one line: file, line, what)."""


def load_plant_module(path: Path):
    """Import the plant file ``path`` as a module of its own (a private name: the file may have
    any name, and the pythonfmu FMU of the same file loaded in this process stays apart)."""
    path = Path(path)
    if not path.is_file():
        raise PlantFileError(f"{path}: no such file")
    if path.suffix != ".py":
        raise PlantFileError(f"{path}: a plant is a Python module (.py)")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", path.stem):
        raise PlantFileError(f"{path}: the file name must be a Python module name")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    name = f"descent_fmus_user_plant_{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        sys.modules.pop(name, None)
        raise PlantFileError(f"{path}:{exc.lineno}: {exc.msg}") from None
    except Exception as exc:                          # noqa: BLE001 -- reported in one line
        sys.modules.pop(name, None)
        where, _ = _where(exc, path)
        raise PlantFileError(f"{where or path}: importing the plant raised "
                             f"{type(exc).__name__}: {exc}") from None
    return module


def plant_class(module, path: Path, name: str | None = None):
    """The FMU class of the plant module: the one :class:`SlaveBase` subclass it defines (or the
    one called ``name``)."""
    from pythonfmu import Fmi2Slave

    from descent_fmus.models.fmu_support import SlaveBase
    own = [c for c in vars(module).values()
           if isinstance(c, type) and c.__module__ == module.__name__]
    found = [c for c in own if issubclass(c, SlaveBase)]
    if name is not None:
        found = [c for c in found if c.__name__ == name]
        if not found:
            raise PlantFileError(f"{path}: no FMU class {name} deriving SlaveBase")
    if not found:
        other = [c.__name__ for c in own if issubclass(c, Fmi2Slave)]
        if other:
            raise PlantFileError(
                f"{path}: {other[0]} derives pythonfmu's Fmi2Slave; a plant with a native twin "
                f"derives descent_fmus.models.fmu_support.SlaveBase and steps an Integrator "
                f"(docs/reference/native-plants.md, 'Your own plant')")
        raise PlantFileError(f"{path}: defines no FMU class (a subclass of SlaveBase)")
    if len(found) > 1:
        raise PlantFileError(f"{path}: several FMU classes ({', '.join(c.__name__ for c in found)})"
                             f"; choose one with --class")
    return found[0]


def _where(exc, path: Path) -> tuple[str, str]:
    """``("file:line", source line)`` of the innermost frame of ``exc`` in the plant's file."""
    target = Path(path).resolve()
    frames = [f for f in traceback.extract_tb(exc.__traceback__)
              if Path(f.filename).resolve() == target]
    if not frames:
        return "", ""
    f = frames[-1]
    return f"{path}:{f.lineno}", (f.line or "").strip()


def _prefix(identifier: str) -> str:
    """The C names' prefix of a plant (lower case; never a C keyword or a runtime name)."""
    p = re.sub(r"[^a-z0-9_]", "_", identifier.lower())
    return p if p not in {"plant", "pc", "py", "fmi2", "model", "double", "int", "float",
                          "char", "if", "else", "return"} else f"{p}_plant"


def build_pythonfmu(source: Path, cls: str, dest_dir: Path) -> Path:
    """The pythonfmu FMU of the class ``cls`` of the plant file ``source``: the module is the
    top-level module ``<cls>_model`` of the FMU's resources (two plant files of one name, or
    two builds of one file, then load side by side in one process), beside the
    ``descent_fmus/models`` modules it imports (as the package's own FMUs)."""
    from descent_fmus.synthesis.fmi.compose import build_bundle, model_closure, model_imports
    needed = set()
    for m in model_imports(Path(source)):
        needed.update(model_closure(m))
    return build_bundle(f"/{cls}_model", cls, sorted(needed), dest_dir,
                        extra=((source, f"{cls}_model.py"),))


def _native_sources(cls, path: Path, dest: Path, compiler=None) -> Path:
    """Trace ``cls`` and compile its native FMU at ``dest``; a construct the tracer cannot
    follow is a PlantFileError naming the line."""
    from descent_fmus.synthesis.fmi.native.builders.plant_fmu import PlantSpec, build_plant_fmu
    from descent_fmus.synthesis.fmi.native.tracer.plant_trace import TraceError
    spec = PlantSpec(cls, _prefix(cls.__name__))
    try:
        return build_plant_fmu(cls.__name__, dest, spec, compiler)
    except TraceError as exc:
        where, line = _where(exc, path)
        raise PlantFileError(f"{where or path}: the native twin cannot be generated: {exc}"
                             + (f" (in: {line})" if line else "")) from None
    except (TypeError, AttributeError, KeyError, IndexError, NotImplementedError) as exc:
        where, line = _where(exc, path)
        if not where:
            raise
        raise PlantFileError(f"{where}: the native tracer cannot follow this line "
                             f"({type(exc).__name__}: {exc})"
                             + (f" (in: {line})" if line else "")) from None


def build_plant(path, dest=None, check: bool = True, class_name: str | None = None,
                steps: int = CHECK_STEPS, step: float | None = None,
                compiler: str | None = None, validate: bool = True) -> dict:
    """Build the pythonfmu FMU and the native twin of the plant file ``path`` into ``dest``
    (default: the file's folder) and check them against each other (see the module
    docstring).  Returns the report (paths, the check's numbers, fmpy's validation, seconds).

    Raises
    ------
    PlantFileError
        The file, its class, or a construct the tracer cannot follow (nothing written).
    """
    from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
    from descent_fmus.synthesis.fmi.native.tracer.plant_trace import TraceError, check_python
    from descent_fmus.synthesis.fmi.native_loop import NATIVE_DIR
    path = Path(path)
    dest = Path(dest) if dest is not None else path.parent
    module = load_plant_module(path)
    cls = plant_class(module, path, class_name)
    ident = cls.__name__
    twin = dest / NATIVE_DIR / f"{ident}.fmu"
    report = {"plant": ident, "file": str(path), "pythonfmu": str(dest / f"{ident}.fmu"),
              "native": None, "check": None, "note": None, "seconds": {}}
    reason = None
    if (compiler or find_compiler()) is None:
        reason = "no C compiler (install gcc or clang, or set CC)"
    else:
        try:
            check_python()
        except TraceError as exc:
            reason = str(exc)
    with tempfile.TemporaryDirectory(prefix="descent_plant_") as tmp:
        t0 = time.perf_counter()
        built = None
        if reason is None:
            from descent_fmus.synthesis.fmi.native.builders.build import NativeBuildError
            try:
                built = _native_sources(cls, path, Path(tmp) / f"{ident}.fmu", compiler)
            except NativeBuildError as exc:          # the generated C: a defect, reported
                reason = report["error"] = f"the generated C did not compile: {exc}"
        report["seconds"]["native"] = round(time.perf_counter() - t0, 2)
        t0 = time.perf_counter()
        dest.mkdir(parents=True, exist_ok=True)
        py = build_pythonfmu(path, ident, dest)
        report["seconds"]["pythonfmu"] = round(time.perf_counter() - t0, 2)
        twin.unlink(missing_ok=True)          # never a twin of an older definition
        if built is None:
            report["note"] = f"native twin not built: {reason}"
        else:
            if check:
                t0 = time.perf_counter()
                report["check"] = _check_in_child(py, built, steps, step)
                report["seconds"]["check"] = round(time.perf_counter() - t0, 2)
            if report["check"] is None or report["check"]["equal"]:
                twin.parent.mkdir(parents=True, exist_ok=True)
                shutil.move(str(built), twin)
                report["native"] = str(twin)
            else:
                report["note"] = "native twin not kept: its flights differ from the pythonfmu FMU's"
    if validate:
        from fmpy.validation import validate_fmu
        report["validate"] = {str(p): validate_fmu(str(p)) for p in (py, twin) if p.is_file()}
    return report


def _check_in_child(py: Path, native: Path, steps: int, step: float | None) -> dict:
    """:func:`check_twins` in a child process (the pythonfmu FMU's Python modules load there,
    apart from the build's)."""
    cmd = [sys.executable, "-m", "descent_fmus.synthesis.fmi.user_plant", str(py),
           str(native), str(steps), repr(step if step is not None else 0.0)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("{")]
    if r.returncode != 0 or not lines:
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return {"equal": False, "error": f"the check flight failed: {tail}"}
    return json.loads(lines[-1])


def _programs(inputs: dict, steps: int) -> list:
    """The check's input programs over the Real inputs (name -> start value): held at the start
    values, a smooth one around them, and one cycling through large, negative and non-finite
    values."""
    def held(k):
        return dict(inputs)

    def smooth(k):
        return {n: s + max(1.0, abs(s)) * math.sin(0.37 * k + j)
                for j, (n, s) in enumerate(inputs.items())}
    wild = (0.0, 1e3, -1e3, math.nan, math.inf, -math.inf, 0.5, -0.5)

    def rough(k):
        return {n: wild[(k + j) % len(wild)] for j, n in enumerate(inputs)}
    return [("held", held), ("smooth", smooth), ("wild", rough)]


def _bits(v) -> bytes:
    return struct.pack("<d", float(v))


def check_twins(py_fmu, native_fmu, steps: int = CHECK_STEPS, step: float | None = None) -> dict:
    """Fly the two FMUs with the same inputs from their default start values and compare every
    output at every communication point bit for bit (the variables by name: the value
    references differ): ``{"equal", "flights", "points", "outputs", "step", "mismatch" (the
    first difference, if any), "statuses"}``."""
    from descent_fmus.synthesis.fmi.slave import load_slave
    fmus = [load_slave(p, name, []) for p, name in ((py_fmu, "py"), (native_fmu, "c"))]
    md = fmus[0].model
    de = md.defaultExperiment
    h = step or (float(de.stepSize) if de is not None and de.stepSize else 0.1)
    inputs = {v.name: float(v.start or 0.0) for v in md.modelVariables
              if v.causality == "input" and v.type == "Real"}
    outs = [(v.name, v.type) for v in md.modelVariables if v.causality == "output"]
    report = {"equal": True, "flights": 0, "points": 0, "outputs": len(outs), "step": h,
              "mismatch": None, "statuses": []}
    try:
        for label, program in _programs(inputs, steps):
            rows = [_fly(f, outs, program, steps, h) for f in fmus]
            report["flights"] += 1
            report["points"] += len(rows[0])
            names = [n for n, _ in outs]
            if "status" in names:
                report["statuses"].append(rows[0][-1][1][names.index("status")])
            bad = _first_difference(rows, outs)
            if bad is not None and report["mismatch"] is None:
                report["equal"] = False
                report["mismatch"] = dict(bad, flight=label)
    finally:
        for f in fmus:
            f.free()
    return report


def _fly(fmu, outs, program, steps, h) -> list:
    vr = {v.name: v.valueReference for v in fmu.model.modelVariables}
    fmu.reset()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    reals = [vr[n] for n, t in outs if t == "Real"]
    ints = [vr[n] for n, t in outs if t != "Real"]

    def read(t):
        r, i = iter(fmu.getReal(reals)), iter(fmu.getInteger(ints) if ints else [])
        return t, [next(r) if kind == "Real" else next(i) for _, kind in outs]
    rows = [read(0.0)]
    for k in range(steps):
        for name, value in program(k).items():
            fmu.setReal([vr[name]], [value])
        fmu.doStep(k * h, h)
        rows.append(read((k + 1) * h))
    return rows


def _first_difference(rows, outs):
    for (t, a), (_, b) in zip(*rows):
        for (name, kind), x, y in zip(outs, a, b):
            if (_bits(x) != _bits(y)) if kind == "Real" else x != y:
                return {"time": t, "output": name, "pythonfmu": x, "native": y}
    return None


if __name__ == "__main__":          # the check's child process: PY NATIVE STEPS STEP
    _py, _c, _n, _h = sys.argv[1:5]
    print(json.dumps(check_twins(_py, _c, int(_n), float(_h) or None), allow_nan=True),
          flush=True)
    sys.stderr.flush()
    # no interpreter teardown after a pythonfmu FMU was loaded (synthesis.cli.main.entry: it
    # was seen, rarely, to abort in glibc's heap checks)
    import os
    os._exit(0)
