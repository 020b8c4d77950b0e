"""The generic controllers as native FMUs: twins of the pythonfmu classes of ``models/controllers/``.

A native twin has the pythonfmu FMU's variables -- read from the Python class itself (names,
start values, descriptions and so units, causality, variability), never written a second time
-- and its behaviour to the last bit, in C with no Python at run time.  The C model of each
twin (``c/<model>.c``) is hand-written once for the generic controller; what it computes comes
from the one Python definition: the network operator's operations are rendered from their table
(:func:`ccode.interpreter_operations_h`), and the value references of the variables the C reads
are generated here (``model_config.h``).

* :func:`build_network_operator_controller` -- ``NetworkOperatorController``: the matrix
  interpreter (``c/no_interp.c``) reading ``psi[i,j]``, ``nx``, ``nq``, ``nu``, ``out[k]`` and
  ``q[k]`` as parameters; a candidate law is a set of start values, never a compile;
* :func:`build_program_controller` -- ``ProgramController`` (the table player).

:data:`GENERIC_TWINS` names the two by model identifier; a system's own twins (S1's sensed and
guided controllers) are built by :func:`build_twin` in the system's package.  ``build_fmus.py``
builds what the systems name into ``fmus/native/``.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from descent_fmus.synthesis.fmi.native.builders.build import Variable, build_fmu
from descent_fmus.synthesis.fmi.native.builders.ccode import interpreter_operations_h

__all__ = ["slave_variables", "layout_config", "program_layout", "with_starts",
           "build_twin", "NO_FILES", "NO_NAMES", "no_capacity",
           "build_network_operator_controller", "build_program_controller",
           "GENERIC_TWINS", "build_native_controllers"]

#: Hand-written C files every twin of a network-operator controller ships.
NO_FILES = ("no_controller.h", "no_interp.c", "no_interp.h")


def slave_variables(cls) -> tuple[list, str]:
    """``(variables, description)`` of the pythonfmu class ``cls``: its FMU variables as
    :class:`~.build.Variable` (the Reals first, then the Integers, each in the class's order)
    with the start values the class's model description declares."""
    from pythonfmu import Fmi2Causality, Fmi2Variability, Integer, Real

    slave = cls(instance_name="native-twin")
    slave.vars.materialise()
    out = {"Real": [], "Integer": []}
    for v in slave.vars.values():
        kind_of = {Fmi2Causality.input: "input", Fmi2Causality.output: "output"}
        if v.causality == Fmi2Causality.parameter:
            kind = "tunable" if v.variability == Fmi2Variability.tunable else "fixed"
        elif v.causality in kind_of:
            kind = kind_of[v.causality]
        else:
            raise ValueError(f"{cls.__name__}.{v.name}: causality {v.causality} has no native "
                             f"kind")
        if isinstance(v, Real):
            out["Real"].append(Variable(v.name, kind, float(v.getter()), v.description))
        elif isinstance(v, Integer):
            out["Integer"].append(Variable(v.name, kind, int(v.getter()), v.description,
                                           type="Integer"))
        else:
            raise ValueError(f"{cls.__name__}.{v.name}: a native FMU holds Reals and Integers "
                             f"only, not {type(v).__name__}")
    return out["Real"] + out["Integer"], cls.description


def layout_config(variables, names: dict, constants: dict | None = None) -> str:
    """``model_config.h`` lines: ``#define MACRO index`` for ``names`` (macro -> the first
    variable of a block, e.g. ``{"VR_X": "x[1]"}``: its index among the Reals, or among the
    Integers for an Integer), the counts ``N_REAL``, ``N_INTEGER`` and the ``constants``."""
    index = {}
    for kind in ("Real", "Integer"):
        index.update((v.name, k) for k, v in enumerate(x for x in variables if x.type == kind))
    lines = [f"#define N_REAL {sum(v.type == 'Real' for v in variables)}",
             f"#define N_INTEGER {max(1, sum(v.type == 'Integer' for v in variables))}"]
    for macro, name in names.items():
        if name not in index:
            raise KeyError(f"no variable {name!r} for {macro}")
        lines.append(f"#define {macro} {index[name]}")
    lines += [f"#define {k} {v}" for k, v in (constants or {}).items()]
    return "/* value references and sizes of the variables the model reads (generated from the " \
           "pythonfmu class) */\n" + "\n".join(lines) + "\n"


#: the variables no_controller.h reads (macro -> the first variable of its block)
NO_NAMES = {"VR_X": "x[1]", "VR_U": "u[1]", "VR_Q": "q[1]", "VR_UMIN": "u_min[1]",
             "VR_UMAX": "u_max[1]", "VR_XSCALE": "x_scale[1]", "VR_XOFFSET": "x_offset[1]",
             "IX_NX": "nx", "IX_NQ": "nq", "IX_NU": "nu", "IX_OUT": "out[1]",
             "IX_PSI": "psi[1,1]"}


def no_capacity() -> dict:
    """The generic controller's capacity (no_controller.h's NO_*_MAX)."""
    from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX, NU_MAX, NX_MAX
    return {"NO_L_MAX": L_MAX, "NO_NX_MAX": NX_MAX, "NO_NQ_MAX": NQ_MAX, "NO_NU_MAX": NU_MAX}


def _no_layout(variables) -> str:
    return layout_config(variables, dict(NO_NAMES, VR_SAMPLE="sample_period"), no_capacity())


def with_starts(variables, defaults: dict | None) -> list:
    """``variables`` with the start values ``defaults`` (name -> value) instead of theirs.

    Raises
    ------
    KeyError
        A name that is no variable, or an output (outputs have no start value).
    """
    defaults = dict(defaults or {})
    settable = {v.name for v in variables if v.kind != "output"}
    unknown = [n for n in defaults if n not in settable]
    if unknown:
        raise KeyError(f"no parameter or input {', '.join(map(repr, unknown[:5]))}")
    return [replace(v, start=int(defaults[v.name]) if v.type == "Integer"
                    else float(defaults[v.name])) if v.name in defaults else v
            for v in variables]


def build_twin(cls, dest, model_file, config, extra_files=(), generated=None,
               compiler=None, defaults=None) -> Path:
    """The native twin of the pythonfmu class ``cls`` at ``dest``: its variables (with the start
    values ``defaults``), ``model_config.h`` from ``config(variables)``, the generated files and
    the hand-written C (``model_file`` and ``extra_files``: names or a system's paths)."""
    variables, description = slave_variables(cls)
    variables = with_starts(variables, defaults)
    files = dict(generated or {})
    files["model_config.h"] = config(variables)
    return build_fmu(dest, cls.__name__, description, variables, files,
                     [model_file, *extra_files], compiler=compiler)


def build_network_operator_controller(dest, compiler: str | None = None,
                                      defaults: dict | None = None) -> Path:
    """The native ``NetworkOperatorController`` (see the module docstring); ``defaults``: other
    start values (e.g. a law's), as the pythonfmu FMU's ``with_defaults``."""
    from descent_fmus.models.controllers.network_operator import NetworkOperatorController
    return build_twin(NetworkOperatorController, dest, "no_model.c", _no_layout, NO_FILES,
                      {"no_operations.h": interpreter_operations_h()}, compiler, defaults)


def build_program_controller(dest, compiler: str | None = None,
                             defaults: dict | None = None) -> Path:
    """The native ``ProgramController`` (the table player ``c/table_model.c``, with the node
    times ``t_node[i]`` of ``grid`` = 1)."""
    from descent_fmus.models.controllers.program_table import (N_CHANNELS, NODES_MAX,
                                                               ProgramController)

    def config(variables):
        return program_layout(variables, NODES_MAX, N_CHANNELS, grid=True)
    return build_twin(ProgramController, dest, "table_model.c", config, compiler=compiler,
                      defaults=defaults)


def program_layout(variables, nodes: int, channels: int, grid: bool) -> str:
    """``model_config.h`` of a piecewise-linear program (``c/table_model.c``, kind 0) with the
    ProgramController's variable names; ``grid``: it has ``grid`` and ``t_node[i]``."""
    names = {"VR_U": "u[1]", "VR_DU": "du[1]", "VR_TEND": "t_end", "VR_TABLE": "table[1,1]",
             "VR_SAMPLE": "sample_period", "IX_N": "n_nodes"}
    if grid:
        names.update(VR_TNODE="t_node[1]", IX_GRID="grid")
    return layout_config(variables, names, {"TABLE_KIND": 0, "TABLE_NODES": nodes,
                                            "TABLE_CHANNELS": channels,
                                            "TABLE_GRID": int(grid)})


#: The twins of the generic controllers (``models/controllers/network_operator.py``,
#: ``program_table.py``) by model identifier; a system that flies them names them among its
#: ``native_controllers``.
GENERIC_TWINS = {"NetworkOperatorController": build_network_operator_controller,
                 "ProgramController": build_program_controller}


def build_native_controllers(out_dir, builders, compiler: str | None = None,
                             say=print) -> list[Path]:
    """Build the native twins ``builders`` (model identifier -> builder, the systems'
    ``native_controllers``) into ``out_dir`` as ``<identifier>.fmu``; ``say`` gets one line per
    FMU, or the one line saying why none is built (no C compiler)."""
    from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
    if (compiler or find_compiler()) is None:
        say("native FMUs skipped: no C compiler (install gcc or clang, or set CC)")
        return []
    out_dir, built = Path(out_dir), []
    for name, build in builders.items():
        t0 = time.perf_counter()
        built.append(build(out_dir / f"{name}.fmu", compiler))
        say(f"built native/{name}.fmu ({time.perf_counter() - t0:.1f} s)")
    return built
