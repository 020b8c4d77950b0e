"""Ending a long run on a signal, and worker processes that never outlive their parent.

Batch systems and container runtimes send SIGTERM before they preempt a job; a user types Ctrl-C
(SIGINT).  Inside :func:`graceful_signals` such a signal ends the run at once, whatever it is
doing -- building a population, refining, computing a reference, exporting laws, waiting for
Dask -- by raising :class:`RunInterrupted` from the handler, but never inside an FMU's own code:

* inside a :func:`critical` section (an in-process flight, the loading of FMUs, the flights of
  the input scaling: code that calls into FMUs) the signal only *requests* the stop, which the
  section raises as soon as it ends (a flight takes milliseconds);
* wherever else it lands, the handler looks at the Python stack it interrupted: if that is a
  pythonfmu FMU's Python code (the FMU's slave object, the pythonfmu package, or a callback an
  FMU calls -- code reached *through* an FMI call, where an exception becomes an FMU error
  reported as "Fatal py exception ... RunInterrupted", not a stop) the stop is deferred: a timer
  (``SIGALRM`` every :data:`RECHECK_SECONDS`) looks again until the FMI call has returned and
  raises there, in the program's own code.

A second signal raises at once in a critical section's own code; inside an FMU's code only a
third does (an FMU that never returns can still be stopped).

Worker processes of a local pool call :func:`watch_parent` in their initialiser: they ignore
SIGINT (the parent handles it and stops them), ask the Linux kernel to send them SIGTERM when
the parent dies (``PR_SET_PDEATHSIG``), and a daemon thread polls the parent's pid as well
(other platforms, and a parent that died before the request took effect).  On SIGTERM a worker
runs its cleanup (removing the FMUs it extracted) and exits at once -- so a run killed by
SIGKILL leaves no process behind.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__ = ["RunInterrupted", "graceful_signals", "check_stop", "stop_requested", "critical",
           "watch_parent", "as_stop", "EXIT_CODES"]

#: Exit codes of ``descent-fmus`` (documented in the README).
EXIT_CODES = {"done": 0, "user error": 2, "SIGINT": 128 + signal.SIGINT,
              "SIGTERM": 128 + signal.SIGTERM}


class RunInterrupted(KeyboardInterrupt):
    """A run stopped on SIGTERM/SIGINT; ``where`` says where it stands (set by the run)."""

    def __init__(self, signum: int, where: str = ""):
        super().__init__(signum, where)
        self.signum = signum
        self.where = where

    @property
    def signal_name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    def __str__(self):
        return f"interrupted by {self.signal_name}" + (f": {self.where}" if self.where else "")


_requested: list = []          # signal numbers received inside graceful_signals()
_critical: list = [0]          # depth of critical() sections


def stop_requested() -> int | None:
    """The signal that requested a stop, or None."""
    return _requested[0] if _requested else None


def check_stop() -> None:
    """Raise :class:`RunInterrupted` if a stop was requested."""
    if _requested:
        raise RunInterrupted(_requested[0])


def as_stop(exc: BaseException) -> RunInterrupted | None:
    """The stop ``exc`` stands for, or None.

    A stop raised inside other code can come out as that code's own error: an import it cut
    short raises ``ImportError`` with the stop as its cause, ctypes reports a stop raised while
    it converted a call's arguments as its ``ArgumentError`` (the stop only in its text).  So
    ``exc`` stands for a stop if it is one, if one is in its cause/context chain, or if a stop
    has been requested (:func:`stop_requested`, inside :func:`graceful_signals`) when it comes
    out.
    """
    seen = set()
    link = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, RunInterrupted):
            return link
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return RunInterrupted(_requested[0]) if _requested else None


#: [choice] How often a stop deferred out of an FMU's code looks again whether the FMI call has
#: returned [s]: a pythonfmu call takes micro- to milliseconds, so the stop is raised within
#: about this delay, and the timer costs nothing while no stop is pending.
RECHECK_SECONDS = 0.02
#: Callbacks the FMUs call (the loggers): their frames count as the FMU's code (an exception
#: raised there would be swallowed by ctypes or reported as the FMU's error).
FMU_CALLBACKS = ("load_slave.<locals>.logger", "printLogMessage")


def _inside_fmu(frame) -> bool:
    """Whether ``frame`` (or a frame below it) is an FMU's own Python code (see the module
    docstring)."""
    fmi2slave = sys.modules.get("pythonfmu.fmi2slave")
    slave = getattr(fmi2slave, "Fmi2Slave", None)
    package = os.path.dirname(getattr(fmi2slave, "__file__", "") or "") or None
    while frame is not None:
        code = frame.f_code
        if getattr(code, "co_qualname", code.co_name) in FMU_CALLBACKS:
            return True
        if package is not None and code.co_filename.startswith(package):
            return True
        if slave is not None and "self" in code.co_varnames \
                and isinstance(frame.f_locals.get("self"), slave):
            return True
        frame = frame.f_back
    return False


def _arm_recheck() -> None:
    if threading.current_thread() is threading.main_thread():
        signal.setitimer(signal.ITIMER_REAL, RECHECK_SECONDS)


def _handler(signum, frame):
    _requested.append(signum)
    in_fmu = _inside_fmu(frame)
    if in_fmu and len(_requested) < 3:
        _arm_recheck()                       # raised once the FMI call has returned
        return
    if len(_requested) > 1 or not _critical[0]:   # outside a critical section, or asked again
        raise RunInterrupted(_requested[0])


def _recheck(signum, frame):
    """SIGALRM after a stop deferred out of an FMU's code: raise it now if the FMI call has
    returned (a critical section raises it itself when it ends)."""
    if not _requested or (_critical[0] and len(_requested) < 2):
        return
    if _inside_fmu(frame):
        _arm_recheck()
        return
    raise RunInterrupted(_requested[0])


@contextlib.contextmanager
def critical():
    """A section a signal must not interrupt (see the module docstring); a stop requested
    inside it is raised when it ends."""
    _critical[0] += 1
    try:
        yield
    finally:
        _critical[0] -= 1
    if not _critical[0]:
        check_stop()


@contextlib.contextmanager
def graceful_signals(signals=(signal.SIGTERM, signal.SIGINT)):
    """Within the block, SIGTERM/SIGINT request a stop (see the module docstring).

    Outside the main thread (where Python cannot install handlers) the block changes nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _handler) for s in signals}
    old[signal.SIGALRM] = signal.signal(signal.SIGALRM, _recheck)
    del _requested[:]
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        for s, h in old.items():
            signal.signal(s, h)
        del _requested[:]


# -- worker side ------------------------------------------------------------------------------
def _set_pdeathsig(sig) -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def watch_parent(parent_pid: int, cleanup=None, poll: float = 0.5) -> None:
    """Make this worker process exit within about ``poll`` seconds of its parent's death.

    ``cleanup()`` runs before the exit (and on SIGTERM from the parent's shutdown path); it must
    only touch files, never the FMUs (it may run while an FMU call is on the stack).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def leave(*_):
        if cleanup is not None:
            try:
                cleanup()
            except Exception:
                pass
        os._exit(0)

    signal.signal(signal.SIGTERM, leave)
    _set_pdeathsig(signal.SIGTERM)
    ppid = os.getppid()

    def parent_gone() -> bool:
        if os.getppid() != ppid:
            return True
        try:
            os.kill(parent_pid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:
            pass
        return False

    if parent_gone():                  # the parent died before the request above took effect
        leave()

    def watch():
        import time
        while not parent_gone():
            time.sleep(poll)
        os.kill(os.getpid(), signal.SIGTERM)     # the handler runs cleanup in the main thread
        time.sleep(5.0)                           # ... unless it is stuck in native code
        os._exit(0)

    threading.Thread(target=watch, name="descent-fmus-parent-watch", daemon=True).start()
