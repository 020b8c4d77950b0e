"""What ends a synthesis run early, and what it leaves: signals, systematic failures, full disks.

:func:`guarded` wraps :func:`synthesis.run.loop.run_synthesis`:

* SIGTERM / SIGINT (a batch system preempting the job, Ctrl-C) request a stop
  (:mod:`synthesis.run.signals`); the run abandons the generation in progress -- the checkpoint of
  the last finished generation is already on disk (written atomically after every generation) --
  stops its workers and raises :class:`~synthesis.run.signals.RunInterrupted` saying where the run
  stands.  ``descent-fmus`` prints that in one line with the command that resumes it and exits
  with 128 + the signal number (130 for SIGINT, 143 for SIGTERM).
* Any other exception (a systematic evaluation failure, a full disk, a bug) also stops the
  workers at once: a local pool, a Dask LocalCluster -- nothing of the run outlives it.
* A run that ends before its first checkpoint (a fresh run stopped in its first generation)
  removes the ``run.json`` it wrote, so that the same command starts it again.
* No space left on the device (ENOSPC) becomes :class:`DiskSpaceError`, naming the folder, the
  size needed and the checkpoint that stays valid; half-written ``*.tmp`` files are removed.
  Before the export of the Pareto laws (tens of kB a law with a native law FMU, about 1 MB
  with the pythonfmu controller, about 2 MB more with the closed-loop FMU and SSP of
  ``--export all``) :func:`check_export_space` compares an estimate with the free space and
  stops before writing anything.
"""
from __future__ import annotations

import errno
import functools
import inspect
import json
import shutil
import tempfile
from pathlib import Path

from descent_fmus.synthesis.run.signals import RunInterrupted, as_stop, graceful_signals

__all__ = ["guarded", "DiskSpaceError", "check_export_space", "export_bytes_per_law"]

_MB = 1024 * 1024
# what the current run last announced it needs: {"what": ..., "bytes": ...}
_NEED: dict = {}


class DiskSpaceError(OSError):
    """Not enough disk space for what the run writes (one line: folder and size needed)."""

    def __init__(self, message: str):
        super().__init__(errno.ENOSPC, message)
        self.message = message

    def __str__(self):
        return self.message


def _mb(n: float) -> str:
    return f"{n / _MB:.1f} MB"


#: Upper bound of a native law FMU [bytes] (the reentry law FMU: about 30 kB).
NATIVE_LAW_FMU_BYTES = 128 * 1024
#: Upper bound of law.json + law.h + law.c of one law [bytes] (reentry: about 15 kB).
LAW_FILES_BYTES = 64 * 1024


def export_bytes_per_law(problem, fmu_dir, closed_loops: bool = True,
                         law_fmu: str = "python") -> tuple[int, int]:
    """(bytes in the run folder, temporary bytes) that exporting one law takes, estimated.

    One exported law is ``law.json``, ``law.h``/``law.c`` (:data:`LAW_FILES_BYTES`) and the law
    FMU: ``law_fmu="native"`` a compiled FMU (:data:`NATIVE_LAW_FMU_BYTES`), ``"python"`` the
    pythonfmu controller with the law as defaults (the controller FMU's size).  With
    ``closed_loops`` add the closed-loop container FMU and its SSP file: the built closed loop
    of the same wiring in the FMU folder gives their sizes (with the pythonfmu controller inside:
    an upper bound for a native law); else the two component FMUs do (container ~ plant +
    controller + 1 MB of container binaries, SSP ~ plant + controller).  Building a container
    extracts and re-packs both components in the temporary folder.
    """
    plant, ctrl = problem.fmu_paths(fmu_dir)
    ps, cs = Path(plant).stat().st_size, Path(ctrl).stat().st_size
    law = NATIVE_LAW_FMU_BYTES if law_fmu == "native" else cs
    per_law, temp = law + LAW_FILES_BYTES, 2 * cs + _MB
    if closed_loops:
        loop = Path(fmu_dir) / f"{problem.wiring.name}.fmu"
        ssp = loop.with_suffix(".ssp")
        if loop.is_file() and ssp.is_file():
            per_law += loop.stat().st_size + ssp.stat().st_size
        else:
            per_law += (ps + cs + _MB) + (ps + cs)
        temp = 4 * (ps + cs) + 8 * _MB
    return int(1.2 * per_law), temp           # 20 % margin


def check_export_space(out: Path, problem, fmu_dir, n_laws: int,
                       closed_loops: bool = True, law_fmu: str = "python") -> None:
    """Raise :class:`DiskSpaceError` before exporting ``n_laws`` laws into ``out/laws`` if the
    estimate (:func:`export_bytes_per_law`) exceeds the free space of ``out`` or of the
    temporary folder."""
    per_law, temp = export_bytes_per_law(problem, fmu_dir, closed_loops, law_fmu)
    need = per_law * n_laws
    _NEED.update(what=f"the export of {n_laws} Pareto laws", bytes=need)
    for folder, size in ((Path(out), need), (Path(tempfile.gettempdir()), temp)):
        free = shutil.disk_usage(folder).free
        if free < size:
            raise DiskSpaceError(
                f"not enough disk space in {folder} for the export of {n_laws} Pareto laws: "
                f"needs about {_mb(size)}, {_mb(free)} free")


def _checkpoint_state(out: Path) -> tuple[bool, str]:
    ck = out / "checkpoint.json"
    if not ck.is_file():
        return False, ""
    try:
        st = json.loads(ck.read_text())
    except (OSError, ValueError):
        return True, f"{ck}"
    if "generation" in st:
        return True, f"generation {st['generation']} in {ck}"
    return True, f"{ck}"


def _remove_partial(out: Path) -> None:
    for tmp in list(out.glob("*.tmp")) + list(out.glob("laws/**/*.tmp")):
        try:
            tmp.unlink()
        except OSError:
            pass


def guarded(run):
    """Decorator for ``run_synthesis(problem, out, fmu_dir, ..., resume=...)`` (see the module
    docstring)."""
    sig = inspect.signature(run)

    @functools.wraps(run)
    def wrapper(*args, **kwargs):
        from descent_fmus.synthesis.run.evaluation import Evaluator
        bound = sig.bind(*args, **kwargs)
        out = Path(bound.arguments["out"])
        resume = bound.arguments.get("resume", False)
        fresh = not (out / "run.json").exists()
        before = set(Evaluator.open_evaluators())
        _NEED.clear()
        try:
            with graceful_signals():
                try:
                    return run(*args, **kwargs)
                except BaseException as exc:
                    # a stop that came out as other code's error (an import it cut short,
                    # ctypes converting a call's arguments) is reported as the stop it is
                    stop = as_stop(exc)
                    if stop is not None and stop is not exc:
                        raise stop from None
                    raise
        except BaseException as exc:
            for ev in set(Evaluator.open_evaluators()) - before:
                ev.close(wait=False)
            saved, where = _checkpoint_state(out)
            if not saved and fresh and not resume and (out / "run.json").is_file():
                (out / "run.json").unlink()       # nothing to resume: the same command restarts
                (out / "flown.bin").unlink(missing_ok=True)
                (out / "journal.jsonl").unlink(missing_ok=True)
            if isinstance(exc, RunInterrupted):
                _remove_partial(out)              # a file the signal cut short
                exc.where = where or "no generation had finished; nothing to resume"
                exc.resumable = saved
                raise
            if isinstance(exc, OSError) and exc.errno == errno.ENOSPC \
                    and not isinstance(exc, DiskSpaceError):
                _remove_partial(out)
                need = (f"{_NEED['what']} needs about {_mb(_NEED['bytes'])}" if _NEED else
                        "the run needs a few MB for its checkpoint and results")
                free = shutil.disk_usage(out if out.exists() else out.parent).free
                kept = (f"the checkpoint ({where}) is intact: free some space and continue "
                        f"with --resume" if saved else "nothing to resume")
                raise DiskSpaceError(f"no space left on the device of {out} ({_mb(free)} "
                                     f"free): {need}; {kept}") from None
            if isinstance(exc, DiskSpaceError) and saved:
                exc.message += (f"; the checkpoint ({where}) is intact: free some space and "
                                f"continue with --resume (or use --no-export)")
                exc.args = (errno.ENOSPC, exc.message)
            raise

    return wrapper
