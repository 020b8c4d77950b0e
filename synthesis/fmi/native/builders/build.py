"""Build native FMUs: a model's C sources + the generic FMI 2.0 (or 3.0) wrapper, compiled here.

A native FMU holds ``modelDescription.xml`` (the variables, ``<SourceFiles>`` naming the C files
to compile), ``sources/`` (everything needed to rebuild it: the generic wrapper ``fmi2_cs.c``,
the model's C files, the FMI 2.0 headers) and ``binaries/<platform>/<identifier>.so`` compiled
here with the system's C compiler.  No Python is involved at run time: the binary depends on the
C library and its math library only.  On another platform, ``fmpy compile X.fmu`` (CMake) or any
FMI tool that builds source FMUs builds it from ``sources/``.  ``fmi_version=3`` writes the FMI 3.0
variant of the same model: the wrapper ``fmi3_cs.c``, the model and build descriptions of the same
variable table (:func:`fmi3_rows`, :mod:`synthesis.fmi.description.fmi3`); :mod:`.fmi3` makes
one of a built FMI 2.0 FMU.

The compiler is ``$CC`` if set, else the first of ``cc``, ``gcc``, ``clang`` on the PATH
(:func:`find_compiler`); none found is :class:`CompilerNotFoundError` (callers fall back to the
pythonfmu controller and say so).
"""
from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
import uuid
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

__all__ = ["C_ROOT", "C_FOLDERS", "c_file", "Variable", "CompilerNotFoundError",
           "NativeBuildError", "find_compiler", "platform_folder", "build_fmu", "compile_sources",
           "cached_library", "COMPILE_FLAGS", "KINDS", "write_native_fmu", "FMI3_WRAPPER_FILES",
           "reusing_objects", "platform_tuple", "fmi3_rows", "FMI3_GENERATION_TOOL"]

#: The hand-written C files shipped as package data, in folders by job: the FMI 2.0 and 3.0
#: wrappers with their vendored headers, the runtime of the traced C, the generic controllers,
#: the C master.
C_ROOT = Path(__file__).resolve().parent.parent / "c"
C_FOLDERS = tuple(C_ROOT / job for job in ("fmi2", "fmi3", "runtime", "controllers", "master"))
#: The FMI 2.0 headers (Modelica Association, 2-clause BSD licence) and the wrapper.
WRAPPER_FILES = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h",
                 "native_model.h", "py_repr.h", "fmi2_cs.c")
#: The FMI 3.0 wrapper: an adapter that compiles the FMI 2.0 wrapper into itself, so it ships
#: those files too, and the FMI 3.0.2 headers.
FMI3_WRAPPER_FILES = WRAPPER_FILES + ("fmi3Functions.h", "fmi3FunctionTypes.h",
                                      "fmi3PlatformTypes.h", "fmi3_cs.c")
#: Flags of the native build.  -ffp-contract=off: no fused multiply-add, so every operation
#: rounds as the Python evaluation does; -fvisibility=hidden: only the FMI functions are
#: exported (they are marked visible by fmi2Functions.h).
COMPILE_FLAGS = ("-fPIC", "-O2", "-std=c99", "-ffp-contract=off", "-fvisibility=hidden",
                 "-Wall")
#: Variable kinds -> (causality, variability, code of native_model.h).
KINDS = {"input": ("input", "continuous", 0), "output": ("output", "continuous", 1),
         "fixed": ("parameter", "fixed", 2), "tunable": ("parameter", "tunable", 3)}


class CompilerNotFoundError(RuntimeError):
    """No C compiler on this machine."""


class NativeBuildError(RuntimeError):
    """The C compiler failed on a native FMU's sources."""


@dataclass(frozen=True)
class Variable:
    """One variable of a native FMU (value references follow the order of the list)."""

    name: str
    kind: str                 #: "input", "output", "fixed" or "tunable"
    start: float = 0.0
    description: str = ""
    type: str = "Real"        #: "Real" or "Integer"


def c_file(name) -> Path:
    """A hand-written C file: a :class:`~pathlib.Path` as given (a system's own C), or a file name
    found in :data:`C_FOLDERS`.

    Raises
    ------
    FileNotFoundError
        No such file in those folders.
    """
    if isinstance(name, Path):
        return name
    for folder in C_FOLDERS:
        if (folder / name).is_file():
            return folder / name
    raise FileNotFoundError(f"no C file {name!r} in {', '.join(f.name for f in C_FOLDERS)}")


def find_compiler() -> str | None:
    """Path of the C compiler: ``$CC`` if set (None if that is not found), else cc/gcc/clang."""
    cc = os.environ.get("CC")
    if cc:
        return shutil.which(cc)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def platform_folder() -> tuple[str, str]:
    """``(binaries/<folder>, shared-library suffix)`` of this machine (FMI 2.0 names)."""
    system, bits = sys.platform, "64" if sys.maxsize > 2 ** 32 else "32"
    if system.startswith("linux"):
        return f"linux{bits}", ".so"
    if system == "darwin":
        return f"darwin{bits}", ".dylib"
    if system in ("win32", "cygwin"):
        return f"win{bits}", ".dll"
    raise NativeBuildError(f"no FMI 2.0 binary folder for platform {system} "
                           f"({platform.machine()})")


def _run(cmd, what) -> None:
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        tail = "\n".join((res.stderr or res.stdout).strip().splitlines()[-12:])
        raise NativeBuildError(f"{Path(cmd[0]).name} failed on {what}:\n{tail}")


# Objects of the hand-written files (the same for every FMU), compiled once per process: a
# synthesis run exports hundreds of laws.  Keyed by compiler, flags and the sources' content.
# Within reusing_objects() the model's files too (their keys in _MODEL_KEYS, dropped at its end).
_OBJECTS: dict = {}
_OBJECT_DIR: list = []
_OBJECTS_LOCK = threading.Lock()
_MODEL_KEYS: set = set()
_REUSING: list = []


@contextmanager
def reusing_objects():
    """Within this block every object compiled for a native FMU is kept, keyed by its sources,
    and reused by the later builds of the process: the FMI 3.0 variant of an FMU built just
    before compiles its wrapper only (``build_fmus.py``).  The objects are dropped at the end."""
    with _OBJECTS_LOCK:
        _REUSING.append(True)
    try:
        yield
    finally:
        with _OBJECTS_LOCK:
            _REUSING.pop()
            if not _REUSING:
                for key in _MODEL_KEYS:
                    _OBJECTS.pop(key).unlink(missing_ok=True)
                _MODEL_KEYS.clear()


def _cached_object(cc: str, sources_dir: Path, name: str) -> Path:
    if name in FMI3_WRAPPER_FILES:
        # the wrapper files it may include (the FMI 3.0 wrapper includes fmi2_cs.c)
        headers = [sources_dir / h for h in FMI3_WRAPPER_FILES
                   if h != name and (sources_dir / h).is_file()]
    else:   # a model file: the model's headers (the wrapper's are those of the package)
        headers = sorted(h for h in sources_dir.glob("*.h") if h.name not in FMI3_WRAPPER_FILES)
    key = hashlib.sha256(repr((cc, COMPILE_FLAGS, name, (sources_dir / name).read_bytes(),
                               [(h.name, h.read_bytes()) for h in headers])).encode()).hexdigest()
    with _OBJECTS_LOCK:                  # laws are exported in parallel threads
        obj = _compiled_object(cc, sources_dir, name, key)
        if name not in FMI3_WRAPPER_FILES:
            _MODEL_KEYS.add(key)
        return obj


def _compiled_object(cc: str, sources_dir: Path, name: str, key: str) -> Path:
    if key not in _OBJECTS:
        if not _OBJECT_DIR:
            _OBJECT_DIR.append(Path(tempfile.mkdtemp(prefix="descent_native_objects_")))
            import atexit
            atexit.register(shutil.rmtree, _OBJECT_DIR[0], True)
        obj = _OBJECT_DIR[0] / f"{key[:20]}.o"
        _run([cc, *COMPILE_FLAGS, "-c", "-I", str(sources_dir), str(sources_dir / name),
              "-o", str(obj)], name)
        _OBJECTS[key] = obj
    return _OBJECTS[key]


def compile_sources(sources_dir: Path, files, library: Path, compiler: str | None = None,
                    cached=(), libraries=("m",), include=()) -> Path:
    """Compile ``files`` of ``sources_dir`` (or paths) into the shared library ``library``;
    ``include``: more folders of headers than ``sources_dir``.

    ``cached``: those of ``files`` whose object may be reused from an earlier build in this
    process (the generic wrapper: it includes only files of :data:`FMI3_WRAPPER_FILES`, which
    are part of the key).

    Raises
    ------
    CompilerNotFoundError, NativeBuildError
    """
    cc = compiler or find_compiler()
    if cc is None:
        raise CompilerNotFoundError(
            "no C compiler found (" + (f"CC={os.environ['CC']} is not on the PATH"
                                       if os.environ.get("CC") else "looked for cc, gcc, clang")
            + "): install one (Debian/Ubuntu: apt-get install gcc) to build native FMUs")
    library.parent.mkdir(parents=True, exist_ok=True)
    # every symbol resolved at link time (a missing function is a build error, not a load error)
    extra = ["-dynamiclib"] if sys.platform == "darwin" else ["-shared", "-Wl,-z,defs"]
    inputs = [str(_cached_object(cc, sources_dir, f)) if f in cached else str(sources_dir / f)
              for f in files]
    folders = [a for d in include for a in ("-I", str(d))]
    _run([cc, *COMPILE_FLAGS, *extra, "-I", str(sources_dir), *folders, *inputs, "-o",
          str(library), *(f"-l{name}" for name in libraries)],
         ", ".join(Path(f).name for f in files))
    if not library.is_file():
        raise NativeBuildError(f"{Path(cc).name} wrote no {library.name}")
    return library


_LIBRARY_LOCK = threading.Lock()


def cached_library(stem: str, files, depends=(), compiler: str | None = None,
                   libraries=("m",)) -> Path:
    """The shared library of the C ``files`` (names or paths, :func:`c_file`), compiled on first
    use into the cache folder (:func:`synthesis.paths.cache_dir`) under a key of the compiler,
    the flags and the sources (``files`` and the headers ``depends`` they include), then found
    there.  The file is written under a private name and renamed, so parallel processes are
    safe.

    Raises
    ------
    CompilerNotFoundError, NativeBuildError
    """
    from descent_fmus.synthesis.paths import cache_dir
    cc = compiler or find_compiler()
    if cc is None:
        raise CompilerNotFoundError("no C compiler found (install gcc, or set CC)")
    paths = [c_file(n) for n in (*files, *depends)]
    key = hashlib.sha256(repr((cc, COMPILE_FLAGS, [(p.name, p.read_bytes()) for p in
                                                   paths])).encode()).hexdigest()
    lib = cache_dir() / stem / f"{stem}-{key[:16]}{platform_folder()[1]}"
    if lib.is_file():
        return lib
    with _LIBRARY_LOCK:
        if lib.is_file():
            return lib
        lib.parent.mkdir(parents=True, exist_ok=True)
        tmp = lib.with_name(f".{lib.name}.{os.getpid()}.{threading.get_ident()}")
        try:               # another process may build it too: each writes its own file
            folders = sorted({p.parent for p in paths})
            compile_sources(folders[0], paths[:len(files)], tmp, cc, libraries=libraries,
                            include=folders[1:])
            os.replace(tmp, lib)
        finally:
            tmp.unlink(missing_ok=True)
    return lib


def _xml(identifier, guid, description, variables, source_files, experiment) -> str:
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(identifier)} '
           f'guid={quoteattr(guid)} description={quoteattr(description)} '
           f'generationTool="descent-fmus (native C export)" '
           f'variableNamingConvention="structured" numberOfEventIndicators="0">',
           f'  <CoSimulation modelIdentifier={quoteattr(identifier)} needsExecutionTool="false" '
           f'canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" '
           f'maxOutputDerivativeOrder="0" canRunAsynchronuously="false" '
           f'canBeInstantiatedOnlyOncePerProcess="false" '
           f'canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="false" '
           f'canSerializeFMUstate="false" providesDirectionalDerivative="false">',
           '    <SourceFiles>']
    out += [f'      <File name={quoteattr(f)}/>' for f in source_files]
    out += ['    </SourceFiles>', '  </CoSimulation>',
            '  <LogCategories>',
            '    <Category name="logStatusError" description="errors (invalid parameters, '
            'calls in the wrong state)"/>',
            '  </LogCategories>']
    if experiment:
        out.append("  <DefaultExperiment " + " ".join(f"{k}={quoteattr(repr(float(v)))}"
                                                       for k, v in experiment.items()) + "/>")
    out.append("  <ModelVariables>")
    outputs = []
    for index, v in enumerate(variables, 1):
        causality, variability, _ = KINDS[v.kind]
        if v.type == "Integer" and variability == "continuous":
            variability = "discrete"
        attrs = (f'name={quoteattr(v.name)} valueReference="{index - 1}" '
                 f'description={quoteattr(v.description)} causality="{causality}" '
                 f'variability="{variability}"')
        if v.kind == "output":
            outputs.append(index)
            out.append(f'    <ScalarVariable {attrs} initial="calculated"><{v.type}/>'
                       f'</ScalarVariable>')
        else:
            start = str(int(v.start)) if v.type == "Integer" else repr(float(v.start))
            init = ' initial="exact"' if v.kind != "input" else ""
            out.append(f'    <ScalarVariable {attrs}{init}><{v.type} start="{start}"/>'
                       f'</ScalarVariable>')
    out.append("  </ModelVariables>")
    out.append("  <ModelStructure>")
    if outputs:
        out.append("    <Outputs>")
        out += [f'      <Unknown index="{i}"/>' for i in outputs]
        out.append("    </Outputs>")
        out.append("    <InitialUnknowns>")
        out += [f'      <Unknown index="{i}"/>' for i in outputs]
        out.append("    </InitialUnknowns>")
    out.append("  </ModelStructure>")
    out.append("</fmiModelDescription>")
    return "\n".join(out) + "\n"


def platform_tuple() -> str:
    """The FMI 3.0 binaries folder of this machine (``x86_64-linux``, ``aarch64-darwin``...)."""
    machine = platform.machine().lower()
    arch = {"amd64": "x86_64", "x64": "x86_64", "arm64": "aarch64"}.get(machine, machine)
    if sys.maxsize <= 2 ** 32 and arch == "x86_64":
        arch = "x86"
    system = ("linux" if sys.platform.startswith("linux") else "darwin"
              if sys.platform == "darwin" else "windows")
    return f"{arch}-{system}"


#: generationTool of the FMI 3.0 variants
FMI3_GENERATION_TOOL = "descent-fmus (native C export, FMI 3.0)"


def fmi3_rows(variables) -> list:
    """The FMI 3.0 description rows of a native FMU's variables (value references in list
    order): the table of the FMI 2.0 description, in the terms of
    :mod:`synthesis.fmi.description.fmi3`."""
    from descent_fmus.synthesis.fmi.description.fmi3 import Row
    return [Row(v.name, vr, KINDS[v.kind][0], KINDS[v.kind][1], v.type,
                None if v.kind == "output" else v.start, v.description)
            for vr, v in enumerate(variables)]


def _fmi3_descriptions(root: Path, identifier: str, guid: str, description: str, variables,
                       c_files, experiment: dict | None) -> None:
    """``modelDescription.xml`` and ``sources/buildDescription.xml`` of an FMI 3.0 native FMU."""
    from descent_fmus.synthesis.fmi.description.fmi3 import build_description, model_description
    (root / "modelDescription.xml").write_bytes(
        model_description(identifier, guid, description, fmi3_rows(variables), experiment,
                          FMI3_GENERATION_TOOL))
    (root / "sources" / "buildDescription.xml").write_bytes(
        build_description(identifier, c_files))


def _with_units(xml: str) -> bytes:
    """The model description with the unit of every Real variable (from the bracket that ends
    its description, as for the pythonfmu FMUs) and its ``<UnitDefinitions>``."""
    from xml.etree import ElementTree as ET

    from descent_fmus.synthesis.fmi.description.units import units_into_model_description
    root = ET.fromstring(xml)
    units_into_model_description(root)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _kind_codes(variables, type_: str) -> str:
    codes = [str(KINDS[v.kind][2]) for v in variables if v.type == type_]
    return ", ".join(codes) or "0"


def build_fmu(dest, identifier: str, description: str, variables, generated: dict,
              model_files, experiment: dict | None = None, compiler: str | None = None,
              fmi_version: int = 2) -> Path:
    """Write the native FMU ``dest``: sources, compiled binary, model description.

    Parameters
    ----------
    dest : path-like
        The ``.fmu`` file (written atomically: a temporary file renamed at the end).
    identifier : str
        Model identifier (a C identifier; also the binary's name).
    description : str
    variables : sequence of Variable
        In value-reference order: the Reals first, then the Integers.
    generated : dict of str -> str
        Generated source files (name -> text), e.g. ``law.c``; ``model_config.h`` gets the GUID
        and start values appended by this function.
    model_files : sequence of str or Path
        Hand-written model files to ship (:func:`c_file`: a name, e.g. ``law_model.c``, or a
        system's own file as a path).
    experiment : dict, optional
        Default experiment (``startTime``, ``stopTime``, ``stepSize``).
    fmi_version : {2, 3}
        The FMI version of the FMU (the same model, the same GUID: the FMI 3.0 instantiation
        token).

    Raises
    ------
    CompilerNotFoundError, NativeBuildError
    """
    dest = Path(dest)
    reals = [v for v in variables if v.type == "Real"]
    ints = [v for v in variables if v.type == "Integer"]
    if [v.type for v in variables] != ["Real"] * len(reals) + ["Integer"] * len(ints):
        raise ValueError("native FMU variables: the Reals first, then the Integers")
    config = generated.get("model_config.h", "")
    # the GUID identifies the FMU's content: same sources, same variables -> same GUID
    names = [c_file(f).name for f in model_files]
    digest = hashlib.sha256(repr((identifier, description, variables, sorted(generated.items()),
                                  names)).encode()).hexdigest()
    guid = "{" + str(uuid.UUID(digest[:32])) + "}"
    config += (f'\n#define MODEL_CONFIG_GUID "{guid}"\n'
               f"#define MODEL_CONFIG_REAL_START "
               + ", ".join(repr(float(v.start)) for v in reals) + "\n"
               f"#define MODEL_CONFIG_REAL_KIND {_kind_codes(variables, 'Real')}\n"
               f"#define MODEL_CONFIG_INTEGER_START "
               + (", ".join(str(int(v.start)) for v in ints) or "0") + "\n"
               f"#define MODEL_CONFIG_INTEGER_KIND {_kind_codes(variables, 'Integer')}\n")
    files = dict(generated, **{"model_config.h": config})
    model_c = [f for f in names if f.endswith(".c")] + sorted(f for f in files if f.endswith(".c"))
    return write_native_fmu(dest, identifier, guid, description, variables, files, model_files,
                            model_c, experiment, compiler, fmi_version)


def write_native_fmu(dest, identifier: str, guid: str, description: str, variables, files: dict,
                     model_files, model_c, experiment: dict | None = None,
                     compiler: str | None = None, fmi_version: int = 2,
                     resources: dict | None = None) -> Path:
    """Compile and write the native FMU ``dest`` of a model whose ``model_config.h`` is final:
    ``files`` (name -> text or bytes: generated sources), ``model_files`` (:func:`c_file`
    names or paths to copy), ``model_c`` (the model's C files to compile, in order) and the
    wrapper of ``fmi_version`` (2: ``fmi2_cs.c``; 3: ``fmi3_cs.c``, an adapter over it, with
    the FMI 3.0 model and build descriptions of the same table: :func:`fmi3_rows`);
    ``resources`` (name -> bytes) go to ``resources/``."""
    dest = Path(dest)
    if fmi_version == 2:
        wrapper, main = WRAPPER_FILES, "fmi2_cs.c"
        folder, suffix = platform_folder()
    elif fmi_version == 3:
        wrapper, main = FMI3_WRAPPER_FILES, "fmi3_cs.c"
        folder, suffix = platform_tuple(), platform_folder()[1]
    else:
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    c_files = [main] + list(model_c)
    with tempfile.TemporaryDirectory(prefix="descent_native_") as tmp:
        root = Path(tmp) / "fmu"
        src = root / "sources"
        src.mkdir(parents=True)
        for name in list(wrapper) + list(model_files):
            shutil.copy(c_file(name), src / c_file(name).name)
        for name, text in files.items():
            (src / name).write_bytes(text if isinstance(text, bytes) else text.encode())
        for name, data in (resources or {}).items():
            (root / "resources").mkdir(exist_ok=True)
            (root / "resources" / name).write_bytes(data)
        compile_sources(src, c_files, root / "binaries" / folder / (identifier + suffix),
                        compiler, cached=c_files if _REUSING else [main])
        if fmi_version == 2:
            (root / "modelDescription.xml").write_bytes(
                _with_units(_xml(identifier, guid, description, variables, c_files, experiment)))
        else:
            _fmi3_descriptions(root, identifier, guid, description, variables, c_files,
                               experiment)
        dest.parent.mkdir(parents=True, exist_ok=True)
        part = dest.with_name(dest.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    z.write(path, path.relative_to(root).as_posix())
        os.replace(part, dest)
    return dest
