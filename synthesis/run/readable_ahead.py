"""The readable forms of a run's Pareto laws, computed while its search runs.

[choice] On a fresh machine SymPy's readable forms were most of the report (about 2.5 s of a
default S1 run's 93 Pareto laws on 2 quiet cores: SymPy's import and ~40 ms a law), while the
search leaves about half a core idle (its main process flies most CMA-ES generations itself).
``descent-fmus synthesize`` therefore forks, before anything else starts, one process at the
lowest priority (nice 19: it takes only CPU time nothing else wants) that watches the run's
``checkpoint.json`` and computes the readable form of every law in its Pareto archive that the
cache folder does not hold yet, keeping each there that SymPy made (:func:`_keep_form`; the
same file :func:`synthesis.fmi.law_files.prefetch_readable` reads).  The report stops it and reads the forms from the cache
folder, computing only those still missing, as before.  The forms are the same text either way
(cached by the law's content, made by the same function), so results do not change; a
machine without ``fork`` or a busy one just leaves more to the report.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

__all__ = ["start", "stop"]

#: Seconds between looks at the checkpoint's modification time.
POLL_SECONDS = 0.25
#: The watcher's niceness: the lowest priority, so that it never slows the search.
NICE = 19

_RUNNING: list = []


def start(out: Path, laws_of):
    """Fork the watcher of ``out/checkpoint.json`` (see the module docstring); None where this
    platform cannot fork.  ``laws_of(checkpoint)``: the laws of a checkpoint's archive (the run
    loop's ``load_archive``; passed in, so that this module does not import the loop that
    imports the report).  Call it before any thread is started (a fork copies no thread, and
    a lock held by one would stay held in the child)."""
    import multiprocessing
    try:
        process = multiprocessing.get_context("fork").Process(
            target=_watch, args=(Path(out) / "checkpoint.json", os.getpid(), laws_of),
            name="descent-fmus-readable-ahead", daemon=True)
        process.start()
    except (ValueError, OSError):          # no fork here: the report computes every form
        return None
    _RUNNING.append(process)
    return process


def stop() -> None:
    """Stop the watchers this process started (they leave at once; a form being written is
    written whole or not at all)."""
    while _RUNNING:
        process = _RUNNING.pop()
        if process.is_alive():
            process.terminate()
        process.join(0.5)


def _watch(checkpoint: Path, parent: int, laws_of) -> None:
    """The watcher's body: compute the missing readable forms of each new checkpoint's
    archive, newest checkpoint first, until stopped or its parent is gone."""
    from descent_fmus.synthesis.fmi.law_files import _law_key, _readable_folder
    from descent_fmus.synthesis.run.signals import watch_parent

    folder = _readable_folder()
    devnull = os.open(os.devnull, os.O_WRONLY)   # nothing of it on the run's output
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    watch_parent(parent, cleanup=lambda: _remove_partial(folder))
    os.nice(NICE)
    seen, mtime = set(), None
    while True:
        try:
            stamp = checkpoint.stat().st_mtime_ns
        except OSError:
            stamp = None
        if stamp is None or stamp == mtime:
            time.sleep(POLL_SECONDS)
            continue
        mtime = stamp
        try:
            laws = laws_of(json.loads(checkpoint.read_text()))
        except (OSError, ValueError, KeyError, TypeError):
            continue                      # being replaced: read again at the next look
        for law in laws:
            key = _law_key(law)
            if key is None or key in seen:
                continue
            _keep_form(folder, key, law)
            seen.add(key)
            if _changed(checkpoint, mtime):
                break                     # a newer archive: its laws first


def _keep_form(folder: Path, key: str, law) -> None:
    """[choice] Keep a law's readable form only if SymPy made it: a form that failed or ran past
    the time limit is left to the report, which computes it as before (the limit counts CPU
    time, the same in this process as in the report's; when it was a real-time limit, this
    lowest-priority process on a busy machine passed it where the report would not: seen in a
    fresh-machine A/B run at load 4, a law's form became its network-operator print)."""
    from descent_fmus.synthesis.fmi.law_files import _compute_readable, _keep
    path = folder / f"{key}.json"
    if path.exists():
        return
    d = _compute_readable(law)
    if "error" not in d:
        _keep(path, d)


def _changed(checkpoint: Path, mtime) -> bool:
    try:
        return checkpoint.stat().st_mtime_ns != mtime
    except OSError:
        return False


def _remove_partial(folder: Path) -> None:
    """The temporary file of a form this process was writing when it was stopped."""
    for path in folder.glob(f".*.{os.getpid()}.tmp"):
        path.unlink(missing_ok=True)
