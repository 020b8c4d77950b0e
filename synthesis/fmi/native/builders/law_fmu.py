"""A network-operator law as a native FMU (C, no Python at run time) and as plain C files.

Two native law FMUs, which fly bitwise the same (tests/fmi/native/test_native_law.py):

* :func:`write_law_fmu` (the default of every export) -- no compile per law: the native
  ``NetworkOperatorController`` (the matrix interpreter, ``c/no_interp.c``), compiled once into
  the cache folder (:func:`interpreter_fmu`), copied with the law's start values in its
  ``modelDescription.xml`` and in ``resources/start_values.txt``, which the wrapper
  (``fmi2_cs.c``) reads at instantiation.  Its variables are the generic controller's at full
  capacity (``x[1..8]``, ``psi[i,j]``, ...), the binary renamed to the law's identifier;
* :func:`build_law_fmu` (``export-law --compiled``, and a law beyond the interpreter's
  capacity) writes an FMI 2.0 co-simulation FMU whose variables are those of the generic
pythonfmu ``NetworkOperatorController`` for this law's sizes -- inputs ``x[1..nx]``, outputs
``u[1..nu]``, tunable parameters ``q[1..nq]``, fixed parameters ``u_min``, ``u_max``,
``x_scale``, ``x_offset``, ``sample_period`` with the same names, descriptions and units -- so
it swaps in for the
controller in any wiring of the project; the matrix is compiled into the code (``psi``, ``nx``,
``out`` are not variables any more).  Its sources: the generic wrapper ``fmi2_cs.c``, the
hand-written ``law_model.c`` and the generated ``law.c`` / ``law.h`` (:func:`ccode.law_c`).
"""
from __future__ import annotations

import hashlib
import os
import re
import threading
import zipfile
from functools import lru_cache
from pathlib import Path

from descent_fmus.models.controllers.network_operator import DESCRIPTIONS
from descent_fmus.models.fmu_support import SAMPLE_PERIOD_DESCRIPTION
from descent_fmus.synthesis.fmi.native.builders.archives import (copied, deflated, raw_members,
                                                                 write_archive)
from descent_fmus.synthesis.fmi.native.builders.build import (COMPILE_FLAGS, WRAPPER_FILES,
                                                              Variable, build_fmu, c_file,
                                                              find_compiler)
from descent_fmus.synthesis.fmi.native.builders.ccode import (c_identifier,
                                                           interpreter_operations_h, law_c)

__all__ = ["law_variables", "build_law_fmu", "law_sources", "DEFAULT_IDENTIFIER",
           "interpreter_fmu", "write_law_fmu", "fits_interpreter"]

DEFAULT_IDENTIFIER = "NetworkOperatorLaw"


def law_variables(law) -> list:
    """The FMU variables of ``law`` in value-reference order (that of ``law_model.c``)."""
    nx, nu = law.nx, len(law.outputs)

    def block(name, kind, values):
        return [Variable(f"{name}[{k + 1}]", kind, v, DESCRIPTIONS[name])
                for k, v in enumerate(values)]

    return (block("x", "input", [0.0] * nx) + block("u", "output", [0.0] * nu)
            + block("q", "tunable", law.q)
            + block("u_min", "fixed", [lo for lo, _ in law.bounds])
            + block("u_max", "fixed", [hi for _, hi in law.bounds])
            + block("x_scale", "fixed", law.input_scale)
            + block("x_offset", "fixed", law.input_offset)
            + [Variable("sample_period", "fixed", 0.0, SAMPLE_PERIOD_DESCRIPTION)])


def law_sources(law, prefix: str, about=()) -> dict:
    """``{"law.h": ..., "law.c": ...}`` of the law with C names ``<prefix>_...``."""
    h, c = law_c(law, prefix=prefix, header="law.h", about=about)
    return {"law.h": h, "law.c": c}


def build_law_fmu(law, dest, identifier: str = DEFAULT_IDENTIFIER, description: str = "",
                  about=(), compiler: str | None = None) -> Path:
    """Write ``law`` as the native FMU ``dest`` (see the module docstring).

    Raises
    ------
    CompilerNotFoundError
        No C compiler (the caller may fall back to the pythonfmu controller).
    NativeBuildError
        The compiler failed.
    """
    ident = c_identifier(identifier)
    files = law_sources(law, ident, about)
    files["model_config.h"] = (
        "/* sizes and names of this law for law_model.c (generated) */\n"
        '#include "law.h"\n'
        f"#define NATIVE_LAW_NX {law.nx}\n#define NATIVE_LAW_NQ {len(law.q)}\n"
        f"#define NATIVE_LAW_NU {len(law.outputs)}\n#define NATIVE_LAW_EVAL {ident}_eval\n")
    text = f"{description or 'network-operator law'}: " + ("; ".join(about) or law.formula(6))
    return build_fmu(dest, ident, text[:2000], law_variables(law), files, ["law_model.c"],
                     compiler=compiler)


# -- the law FMU from the interpreter: no compile per law ------------------------------------
_TEMPLATE_LOCK = threading.Lock()


def interpreter_fmu(compiler: str | None = None) -> Path:
    """The native ``NetworkOperatorController`` FMU (:mod:`.controllers`), compiled on first use
    into the cache folder (:func:`synthesis.paths.cache_dir`) under a key of the compiler, the
    flags, the C files, the generated operation table and the controller's variables, then
    found there (the key is computed
    once per process and compiler).

    Raises
    ------
    CompilerNotFoundError, NativeBuildError
    """
    from descent_fmus.synthesis.fmi.native.builders.build import CompilerNotFoundError
    from descent_fmus.synthesis.fmi.native.builders.controllers import (
        NO_FILES, build_network_operator_controller)
    from descent_fmus.synthesis.paths import cache_dir
    folder = cache_dir() / "law_interpreter"
    memo = (compiler, os.environ.get("CC"), os.environ.get("PATH"), folder)
    with _TEMPLATE_LOCK:
        if memo not in _INTERPRETERS:
            cc = compiler or find_compiler()
            if cc is None:
                raise CompilerNotFoundError("no C compiler found (install gcc or clang, or set "
                                            "CC) to build the native network-operator "
                                            "interpreter")
            files = [c_file(n) for n in (*WRAPPER_FILES, *NO_FILES, "no_model.c")]
            # the generated operation table is a source too: a new operation, a new key
            key = hashlib.sha256(repr((cc, COMPILE_FLAGS, [(p.name, p.read_bytes())
                                                           for p in files],
                                       interpreter_operations_h(),
                                       _controller_variables())).encode()).hexdigest()
            _INTERPRETERS[memo] = (cc, folder / f"NetworkOperatorController-{key[:16]}.fmu")
        cc, path = _INTERPRETERS[memo]
        if not path.is_file():        # written under a private name and renamed: parallel-safe
            tmp = path.with_name(f".{path.stem}.{os.getpid()}.{threading.get_ident()}.fmu")
            try:
                build_network_operator_controller(tmp, cc)
                os.replace(tmp, path)
            finally:
                tmp.unlink(missing_ok=True)
    return path


_INTERPRETERS: dict = {}


@lru_cache(maxsize=1)
def _controller_variables() -> tuple:
    from descent_fmus.models.controllers.network_operator import NetworkOperatorController
    from descent_fmus.synthesis.fmi.native.builders.controllers import slave_variables
    return tuple(slave_variables(NetworkOperatorController)[0])


def fits_interpreter(law) -> bool:
    """Whether the interpreter holds ``law`` (its nodes, inputs, parameters, outputs)."""
    from descent_fmus.synthesis.methods.law_fmu import CapacityError
    try:
        law.start_values()
    except CapacityError:
        return False
    return True


#: a ScalarVariable's name, value reference and the span of its start value
_START = re.compile(rb'<ScalarVariable name="([^"]*)" valueReference="(\d+)"[^>]*>\s*'
                    rb'<(Real|Integer)\b[^>]*?start="([^"]*)"')
_HEADER = re.compile(rb'(modelName|description|modelIdentifier)="[^"]*"')


class _Template:
    """The interpreter FMU read once: its members, and its model description cut at the start
    values and the header's names."""

    def __init__(self, path: Path):
        with zipfile.ZipFile(path) as z:
            xml = z.read("modelDescription.xml")
        self.members = [(i, d) for i, d in raw_members(path)
                        if i.filename != "modelDescription.xml"]
        self.identifier = re.search(rb'modelIdentifier="([^"]*)"', xml).group(1).decode()
        self.slots, self.pieces, self.starts, pos = {}, [], {}, 0
        for m in _START.finditer(xml):
            self.pieces.append(xml[pos:m.start(4)])
            name, integer = m.group(1).decode(), m.group(3) == b"Integer"
            self.slots[name] = (len(self.pieces), int(m.group(2)), integer)
            self.starts[name] = int(m.group(4)) if integer else m.group(4).decode()
            self.pieces.append(m.group(4))
            pos = m.end(4)
        self.pieces.append(xml[pos:])
        end = self.pieces[0].index(b"<ModelVariables")
        self.head, self.pieces[0] = self.pieces[0][:end], self.pieces[0][end:]

    def changed(self, values: dict) -> dict:
        """``{name: start literal}`` of the ``values`` that are not the interpreter's own start
        values (its compiled ones: the Integers compared as numbers, the Reals by their
        literal, so that -0.0 and 0.0 differ)."""
        out, starts, slots = {}, self.starts, self.slots
        for name, v in values.items():
            if slots[name][2]:
                if int(v) != starts[name]:
                    out[name] = str(int(v))
            else:
                text = repr(float(v))
                if text != starts[name]:
                    out[name] = text
        return out

    def model_description(self, identifier: str, description: str, values: dict) -> bytes:
        from xml.sax.saxutils import quoteattr
        names = {b"modelName": identifier, b"modelIdentifier": identifier,
                 b"description": description}
        head = _HEADER.sub(lambda m: m.group(1) + b"=" + quoteattr(
            names[m.group(1)]).encode(), self.head)
        pieces = list(self.pieces)
        for name, text in values.items():
            pieces[self.slots[name][0]] = text.encode()
        return head + b"".join(pieces)

    def start_values(self, values: dict) -> str:
        return "# value reference, start value, name: read by fmi2_cs.c at instantiation\n" + \
            "".join(f"{self.slots[n][1]} {t} {n}\n" for n, t in values.items())


@lru_cache(maxsize=4)
def _template(path: Path, stamp) -> _Template:
    return _Template(path)


def write_law_fmu(law, dest, identifier: str = DEFAULT_IDENTIFIER, description: str = "",
                  about=(), compiler: str | None = None) -> Path:
    """Write ``law`` as the native FMU ``dest`` with no compile: the interpreter FMU with the
    law's start values (see the module docstring).

    Raises
    ------
    CapacityError
        The law does not fit the interpreter (:func:`fits_interpreter`; :func:`build_law_fmu`
        compiles any law).
    CompilerNotFoundError, NativeBuildError
        The interpreter is not built yet and cannot be.
    """
    ident = c_identifier(identifier)
    path = interpreter_fmu(compiler)
    tpl: _Template = _template(path, path.stat().st_mtime_ns)
    values = tpl.changed(law.start_values())
    text = f"{description or 'network-operator law'}: " + ("; ".join(about) or law.formula(6))
    xml = tpl.model_description(ident, text[:2000], values)
    binary = f"/{tpl.identifier}."
    entries = [deflated("modelDescription.xml", xml)]
    for info, data in tpl.members:     # copied as they are compressed: no compression per law
        name = info.filename
        if name.startswith("binaries/") and binary in name:
            name = name.replace(binary, f"/{ident}.")
        entries.append(copied(name, info, data))
    entries.append(deflated("resources/start_values.txt", tpl.start_values(values).encode()))
    return write_archive(dest, entries)


