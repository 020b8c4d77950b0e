"""Ending a long run on a signal, and worker processes that never outlive their parent.

Batch systems and container runtimes send SIGTERM before they preempt a job; a user types Ctrl-C
(SIGINT).  Inside :func:`graceful_signals` such a signal ends the run at once, whatever it is
doing -- building a population, refining, computing a reference, exporting laws, waiting for
Dask -- by raising :class:`RunInterrupted` from the handler, except inside a :func:`critical`
section: there (an in-process flight, where the FMUs' Python code runs in this process and an
exception thrown into an FMU callback would become an FMU error, not a stop) the signal only
*requests* the stop, which :func:`check_stop` raises as soon as the section ends (a flight
takes milliseconds).  A second signal raises at once, critical or not.

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
           "watch_parent", "EXIT_CODES"]

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


def _handler(signum, frame):
    _requested.append(signum)
    if len(_requested) > 1 or not _critical[0]:   # outside a critical section, or asked twice
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
    del _requested[:]
    try:
        yield
    finally:
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
