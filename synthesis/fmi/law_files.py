"""A network-operator law as files: JSON with its readable form, C, the law FMU, the closed loop.

:func:`export_law_files` writes ``law.json`` (the law and its readable form), ``law.h`` /
``law.c`` (a plain C function, no FMI, for flight software: source text, not compiled), the law
FMU -- native (C, no Python in the host: :mod:`synthesis.fmi.native`) where a C compiler exists,
else the pythonfmu ``NetworkOperatorController`` with the law as defaults -- and, if asked, the closed-loop FMU and
SSP of the law's problem, built around that law FMU.  ``descent-fmus export-law`` and a
synthesis run's export (:class:`LawExport`) use it.

[choice] The native law FMU is by default the compiled network-operator interpreter with the
law's start values (:func:`~synthesis.fmi.native.builders.law_fmu.write_law_fmu`): no compile
per law, so a run's ~100 Pareto laws export in well under a second (a compile per law took
~6 s for 106 laws); it flies bitwise as the law FMU compiled from ``law.c``, which
``compiled=True`` (``export-law --compiled``) still builds for the laws a user picks, and which
a law beyond the interpreter's capacity gets anyway.
"""
from __future__ import annotations

import json
import os
import signal
import threading
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

__all__ = ["LawExport", "choose_law_fmu", "export_law_files", "law_document", "law_json_text",
           "readable_text", "prefetch_readable"]


@dataclass(frozen=True)
class LawExport:
    """What a synthesis run exports for every Pareto law (``run_synthesis(export=...)``).

    Always ``law.json`` (with the readable form), ``law.h``/``law.c`` and the law FMU.

    Attributes
    ----------
    law_fmu : {"auto", "native", "python"}
        The law FMU: native (compiled C), the pythonfmu controller with the law as defaults, or
        native where a C compiler exists and pythonfmu otherwise (with a note).
    closed_loops : bool
        Also the closed-loop FMU (plant + law FMU) and its SSP file per law (about 1.7 MB a law:
        each carries the pythonfmu plant).
    compiled : bool
        A native law FMU compiled from the law's C per law instead of the interpreter with the
        law's start values (the same flights; about 50 ms a law more).
    """

    law_fmu: str = "auto"
    closed_loops: bool = True
    compiled: bool = False

    def __post_init__(self):
        if self.law_fmu not in ("auto", "native", "python"):
            raise ValueError(f"law_fmu must be 'auto', 'native' or 'python', got "
                             f"{self.law_fmu!r}")

    @classmethod
    def of(cls, export) -> "LawExport | None":
        """``export`` of ``run_synthesis``: True (everything), False/None (nothing) or a
        LawExport."""
        if isinstance(export, cls):
            return export
        return cls() if export else None


def choose_law_fmu(law_fmu: str = "auto") -> tuple[str, str]:
    """``("native" | "python", note)``: the kind of law FMU to build on this machine.

    ``"auto"`` is native where a C compiler exists; otherwise pythonfmu, and ``note`` says why.

    Raises
    ------
    CompilerNotFoundError
        ``"native"`` asked and no C compiler found.
    """
    from descent_fmus.synthesis.fmi.native.builders.build import (CompilerNotFoundError,
                                                                  find_compiler)
    if law_fmu == "python":
        return "python", ""
    if find_compiler() is not None:
        return "native", ""
    if law_fmu == "native":
        raise CompilerNotFoundError("no C compiler found (install gcc or clang, or set CC) to "
                                    "build a native law FMU; --python exports the pythonfmu "
                                    "controller instead")
    return "python", ("no C compiler found (install gcc or clang, or set CC): laws exported "
                      "as pythonfmu controller FMUs, which need Python in the host")


#: [choice] Seconds SymPy may take over one law's readable form.  Its automatic evaluation of
#: some laws (nested powers of sums, as genetic programming grows them: each ``tanh``/``sin``
#: asks whether its argument is zero, and SymPy expands the powers to answer) ran for minutes
#: without end in a run's report; a law usually takes 30-50 ms.  Past the limit the law's
#: network-operator print stands in (its ``error`` says so) and is kept like any other form.
#: The seconds are the process's CPU time, not the clock's: a busy machine (other jobs taking
#: the core) must not turn a form SymPy makes into the stand-in, or a seeded run's
#: ``pareto.json`` would depend on the machine's load.
READABLE_SECONDS = 3.0


class ReadableTimeout(BaseException):
    """SymPy took longer than :data:`READABLE_SECONDS` over a law's readable form (a
    BaseException: SymPy catches ``Exception`` in places, which would swallow it)."""


#: after the limit, the timeout is raised again this often until it leaves SymPy
READABLE_RETRY_SECONDS = 0.2


@contextmanager
def _time_limit(seconds: float):
    """Raise :class:`ReadableTimeout` in this block after ``seconds`` of the process's CPU
    time and again every :data:`READABLE_RETRY_SECONDS` until the block ends (a CPU-time
    timer, ``ITIMER_PROF``: only in the main thread, where signals are delivered; elsewhere no
    limit)."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal,
                                                                                "setitimer"):
        yield
        return

    def expired(signum, frame):
        raise ReadableTimeout(f"SymPy took over {seconds:g} s")

    previous = signal.signal(signal.SIGPROF, expired)
    signal.setitimer(signal.ITIMER_PROF, seconds, READABLE_RETRY_SECONDS)
    try:
        yield
    finally:
        while True:     # a timeout pending while the timer is disarmed: disarm again
            try:
                signal.setitimer(signal.ITIMER_PROF, 0)
                signal.signal(signal.SIGPROF, previous)
                break
            except ReadableTimeout:
                continue


def _compute_readable(law) -> dict:
    try:
        with _time_limit(READABLE_SECONDS):
            return law.readable().to_dict()
    except (Exception, ReadableTimeout) as exc:   # SymPy failing or too slow on a law: the
        # law is still exported
        return {"text": law.formula(6), "error": f"{type(exc).__name__}: {exc}"}


def _readable(law) -> dict:
    key = _law_key(law)
    if key is None:
        return _compute_readable(law)
    if key not in _READABLE:
        if len(_READABLE) > 4096:
            _READABLE.clear()
        _READABLE[key] = _compute_readable(law)
    return _READABLE[key]


# -- the readable forms of a run's Pareto laws, at once ----------------------------------------
#: This process's readable forms by law content (:func:`_law_key`).
_READABLE: dict = {}
#: [choice] SymPy takes ~30-50 ms a law (a run's ~100 Pareto laws: most of the report's time), so
#: :func:`prefetch_readable` keeps each law's readable form in the cache folder under the law's
#: content and the formula code's, and computes the missing ones in forked processes (SymPy
#: imported before the fork; worth it from this many laws a process on).
LAWS_PER_PROCESS = 12


def _law_key(law) -> str | None:
    """The content key of a network-operator law (None for any other kind of law)."""
    import hashlib

    from descent_fmus.synthesis.methods.law import NetworkOperator
    if type(law) is not NetworkOperator:
        return None
    d = law.to_dict(formula=False)
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:24]


def _readable_folder() -> Path:
    """The cache folder of readable forms: keyed by the code that makes them (the formula
    module, the operation table, the law class) and SymPy's version."""
    import hashlib
    from importlib.metadata import version

    from descent_fmus.models.controllers import operation_table
    from descent_fmus.synthesis.methods import law, law_formula
    from descent_fmus.synthesis.paths import cache_dir
    h = hashlib.sha256(version("sympy").encode())
    for module in (law_formula, operation_table, law):
        h.update(Path(module.__file__).read_bytes())
    return cache_dir() / f"readable-{h.hexdigest()[:16]}"


def prefetch_readable(laws, processes: int | None = None, meanwhile=None,
                      initializer=None) -> None:
    """Make the readable forms of ``laws`` ready for :func:`readable_text` and
    :func:`law_document`: read from the cache folder (:func:`_readable_folder`), the others
    computed -- across ``processes`` worker processes (default: one per
    :data:`LAWS_PER_PROCESS` laws, at most one per core; ``meanwhile()`` runs here while they
    work, or first) -- and kept there.  ``initializer()`` runs first in every worker process
    (a run passes one that ends the worker with its parent: a run killed while its report is
    written leaves no process behind)."""
    folder = _readable_folder()
    todo = {}
    for law in laws:
        key = _law_key(law)
        if key is None or key in _READABLE or key in todo:
            continue
        try:
            _READABLE[key] = json.loads((folder / f"{key}.json").read_text())
        except (OSError, ValueError):
            todo[key] = law
    n = processes or min(os.cpu_count() or 1, len(todo) // LAWS_PER_PROCESS)
    if n > 1:
        done = _in_processes(list(todo.values()), n, meanwhile, initializer)
    else:
        if meanwhile is not None:
            meanwhile()
        done = [None] * len(todo)
    for (key, law), d in zip(todo.items(), done):
        _READABLE[key] = d = d if d is not None else _compute_readable(law)
        if "error" not in d or d["error"].startswith(ReadableTimeout.__name__):
            _keep(folder / f"{key}.json", d)


def _in_processes(laws, n: int, meanwhile=None, initializer=None) -> list:
    """:func:`_compute_readable` of ``laws`` in ``n`` forked processes (SymPy imported here
    first, so that they start with it; ``initializer()`` run first in each), ``meanwhile()``
    run here while they work; Nones if they cannot run (the caller computes those here)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    import sympy  # noqa: F401
    try:
        with ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork"),
                                 initializer=initializer) as pool:
            done = pool.map(_compute_readable, laws, chunksize=max(1, -(-len(laws) // n)))
            if meanwhile is not None:
                meanwhile()
            return list(done)
    except (OSError, ValueError, RuntimeError):   # no fork or no processes here
        return [None] * len(laws)


def _keep(path: Path, d: dict) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(d))
        os.replace(tmp, path)
    except OSError:               # a read-only cache: computed again next time
        pass


def readable_text(law) -> str:
    """The law's readable form as one line (its network-operator print if SymPy fails)."""
    return _readable(law)["text"]


def law_document(law, extra: dict | None = None) -> dict:
    """``law.json``: the law (``NetworkOperator.to_dict``), its readable form (``readable``:
    ``text``, ``latex``, ``exact``, ``functions``) and ``extra`` fields."""
    d = law.to_dict()
    d["readable"] = _readable(law)
    d.update(extra or {})
    return d


def law_json_text(doc: dict) -> str:
    """The text of ``law.json``: one field a line, the matrix one row a line (json's C encoder,
    which ``indent`` would replace by its Python one: 8 ms a law)."""
    def field(key, value):
        if key == "psi":
            return f'"psi": [\n  ' + ",\n  ".join(json.dumps(r) for r in value) + "\n ]"
        return f"{json.dumps(key)}: {json.dumps(value)}"
    return "{\n " + ",\n ".join(field(k, v) for k, v in doc.items()) + "\n}\n"


def _write_text(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def export_law_files(law, dest, law_fmu: str = "auto", fmu_dir=None,
                     identifier: str | None = None, description: str = "", problem=None,
                     closed_loop: bool = False, extra: dict | None = None,
                     compiled: bool = False) -> dict:
    """Write a law's files into the folder ``dest`` (created if absent).

    Parameters
    ----------
    law : NetworkOperator
    dest : path-like
    law_fmu : {"auto", "native", "python"}
        See :class:`LawExport`.
    fmu_dir : path-like, optional
        Folder of the built FMUs (needed for a pythonfmu law FMU and for the closed loop).
    identifier : str, optional
        Model identifier of the native FMU (its file is ``<identifier>.fmu``) and prefix of the
        C names (default ``NetworkOperatorLaw``).
    description : str
    problem : SynthesisProblem, optional
        The law's problem: its controller FMU (pythonfmu) and, with ``closed_loop``, its wiring
        and plant FMU.
    closed_loop : bool
        Also ``<wiring name>.fmu`` (container: plant + law FMU) and ``<wiring name>.ssp``; the
        plant parameters the problem sets per initial state stay parameters of the container.
    extra : dict, optional
        More fields of ``law.json`` (e.g. the problem's name, the law's objectives).
    compiled : bool
        The native law FMU compiled from ``law.c`` (else the interpreter with the law's start
        values, unless the law does not fit it).

    Returns
    -------
    dict
        Paths (``law_json``, ``law_h``, ``law_c``, ``controller_fmu`` and, with ``closed_loop``,
        ``closed_loop_fmu``, ``ssp``), ``closed_loop_plant`` ("native": the plant's native twin,
        where built, or "pythonfmu"), ``law_fmu`` ("native" or "python") and ``note`` (why not
        native, if so).

    Raises
    ------
    CompilerNotFoundError
        ``law_fmu="native"`` and no C compiler.
    NativeBuildError, FMUNotFoundError, ValueError
    """
    from descent_fmus.synthesis.fmi.native.builders.ccode import c_identifier
    from descent_fmus.synthesis.fmi.native.builders.law_fmu import (
        DEFAULT_IDENTIFIER, build_law_fmu, fits_interpreter, law_sources, write_law_fmu)
    kind, note = _law_fmu_kind(law_fmu, problem)
    if (kind == "python" or closed_loop) and fmu_dir is None:
        raise ValueError("a pythonfmu law FMU or a closed loop needs the folder of the built "
                         "FMUs (fmu_dir)")
    if closed_loop and problem is None:
        raise ValueError("a closed-loop FMU needs the law's problem")
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    ident = c_identifier(identifier or DEFAULT_IDENTIFIER)
    doc = law_document(law, extra)
    about = doc["readable"]["text"].split("; ")
    out = {"law_json": str(_write_text(dest / "law.json", law_json_text(doc)))}
    for name, text in law_sources(law, ident, about).items():
        out[name.replace(".", "_")] = str(_write_text(dest / name, text))
    what = description or "network-operator law"
    if kind == "native":
        build = build_law_fmu if compiled or not fits_interpreter(law) else write_law_fmu
        ctrl = build(law, dest / f"{ident}.fmu", ident, what, about)
    else:
        ctrl = _python_law_fmu(law, dest, fmu_dir, problem, f"{what}: {doc['readable']['text']}")
    out.update(controller_fmu=str(ctrl), law_fmu=kind, note=note)
    if closed_loop:
        out.update(_closed_loop_files(problem, fmu_dir, ctrl, dest,
                                      f"{description or problem.wiring.description}; law "
                                      f"{doc['readable']['text']}"))
    return out


def _law_fmu_kind(law_fmu: str, problem) -> tuple[str, str]:
    """:func:`choose_law_fmu` for ``problem``: ``("native" | "python", note)``.

    The native law FMU stands in for the generic controller only; a problem's own controller
    FMU (e.g. one carrying a sensor estimate) is exported with the law as defaults.
    """
    kind, note = choose_law_fmu(law_fmu)
    if kind == "native" and problem is not None and \
            problem.wiring.controller != "NetworkOperatorController":
        kind, note = "python", (f"{problem.wiring.controller} does more than the law: exported "
                                f"as that pythonfmu FMU with the law as defaults")
    return kind, note


def _python_law_fmu(law, dest: Path, fmu_dir, problem, description: str) -> Path:
    """The pythonfmu law FMU in ``dest``: the problem's controller FMU (default the generic
    ``NetworkOperatorController``) from ``fmu_dir`` with the law as defaults."""
    from descent_fmus.synthesis.fmi.compose import with_defaults
    src = (problem.fmu_paths(fmu_dir)[1] if problem is not None
           else Path(fmu_dir) / "NetworkOperatorController.fmu")
    return with_defaults(src, dest / Path(src).name, law.start_values(),
                         description=description[:2000])


def _closed_loop_files(problem, fmu_dir, ctrl: Path, dest: Path, description: str) -> dict:
    """``<wiring name>.fmu`` (container: the problem's plant + the law FMU ``ctrl``) and
    ``<wiring name>.ssp`` in ``dest``; the plant parameters the problem sets per initial state
    stay parameters of the container.  The plant is its native twin where one is built
    (``<fmu_dir>/native/<plant>.fmu``, checked bit for bit against the pythonfmu plant when it
    was built), else the pythonfmu plant.  Returns the paths (``closed_loop_fmu``, ``ssp``) and
    ``closed_loop_plant`` ("native" or "pythonfmu": the plant inside)."""
    from descent_fmus.synthesis.fmi.containers import closed_loop_fmu, write_ssp
    from descent_fmus.synthesis.fmi.native_loop import twin_of
    w = problem.wiring
    own = problem.fmu_paths(fmu_dir)[0]
    twin = twin_of(own, w.plant)
    plant_fmu = twin or own
    wl = replace(w, description=description[:2000])
    names = list(dict.fromkeys(k for s in problem.initial_states for k in s))
    plant_params = tuple((n, "plant", n) for n in names)
    return {"closed_loop_fmu": str(closed_loop_fmu(wl, plant_fmu, ctrl, dest / f"{w.name}.fmu",
                                                   parameters=plant_params)),
            "ssp": str(write_ssp(wl, plant_fmu, ctrl, dest / f"{w.name}.ssp")),
            "closed_loop_plant": "native" if twin is not None else "pythonfmu"}
