"""A network-operator law as a native FMU (C, no Python at run time) and as plain C files.

:func:`build_law_fmu` writes an FMI 2.0 co-simulation FMU whose variables are those of the generic
pythonfmu ``NetworkOperatorController`` for this law's sizes -- inputs ``x[1..nx]``, outputs
``u[1..nu]``, tunable parameters ``q[1..nq]``, fixed parameters ``u_min``, ``u_max``,
``x_scale``, ``x_offset``, ``sample_period`` with the same names, descriptions and units -- so
it swaps in for the
controller in any wiring of the project; the matrix is compiled into the code (``psi``, ``nx``,
``out`` are not variables any more).  Its sources: the generic wrapper ``fmi2_cs.c``, the
hand-written ``law_model.c`` and the generated ``law.c`` / ``law.h`` (:func:`ccode.law_c`).
"""
from __future__ import annotations

from pathlib import Path

from descent_fmus.models.controllers.network_operator import DESCRIPTIONS
from descent_fmus.models.fmu_support import SAMPLE_PERIOD_DESCRIPTION
from descent_fmus.synthesis.fmi.native.builders.build import Variable, build_fmu
from descent_fmus.synthesis.fmi.native.builders.ccode import c_identifier, law_c

__all__ = ["law_variables", "build_law_fmu", "law_sources", "DEFAULT_IDENTIFIER"]

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
