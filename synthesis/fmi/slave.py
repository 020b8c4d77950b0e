"""One FMU loaded for a master: extracted, instantiated once, its log and callbacks kept.

:func:`load_slave` gives a :class:`LoadedFMU` (fmpy's ``FMU2Slave`` with its model description,
folder, log and callbacks); :class:`FMUError` is what a failed FMU call raises, with what the FMU
said.  The closed loops (:mod:`.closed_loop`, :mod:`.container_loop`) and the tests load their
FMUs here.

A pythonfmu 0.7 binary loaded as it is (a user's FMU built by pythonfmu alone: this package's
own pythonfmu FMUs carry a C wrapper that does the same) writes to freed memory when the process
exits: the C++ exit handler destroys its static interpreter-state pointer, then the library's
destructor function (``finalizePythonInterpreter``) releases the stale pointer again, which glibc
may report as ``corrupted double-linked list``.  :func:`load_slave` therefore has that function
called once at this interpreter's exit (:func:`_release_pythonfmu_state`), before the C exit
handlers: the state is released while the pointer is valid, and both later releases find it null.
"""
from __future__ import annotations

import atexit
import ctypes
import os
import shutil

from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from descent_fmus.synthesis.paths import require_fmu

__all__ = ["FMUError", "LoadedFMU", "load_slave", "CFunctions", "not_an_output"]


class FMUError(RuntimeError):
    """An FMU call failed; the message carries what the FMU logged."""


class LoadedFMU:
    """An extracted and instantiated FMI 2.0 co-simulation FMU (fmpy's ``FMU2Slave``) with what
    this package keeps beside it: the model description, the folder it was extracted to, the
    FMU's log and the ctypes callbacks that must outlive the instance.  FMI calls are fmpy's:
    ``loaded.getReal(...)`` is ``loaded.slave.getReal(...)``."""

    def __init__(self, slave: FMU2Slave, model, unzipdir: str, log: list | None, callbacks):
        self.slave, self.model, self.unzipdir, self.log = slave, model, unzipdir, log
        self._callbacks = callbacks

    def __getattr__(self, name):
        # only reached for names this wrapper does not define: fmpy's FMI functions
        return getattr(self.__dict__["slave"], name)

    def remove_files(self) -> None:
        """Delete the extracted folder (files only: no FMU call)."""
        shutil.rmtree(self.unzipdir, ignore_errors=True)

    def free(self) -> None:
        """Terminate, free the instance and delete its folder."""
        try:
            self.slave.terminate()
        except Exception:
            pass
        try:
            self.slave.freeInstance()
        finally:
            self.remove_files()


def load_slave(path, instance_name: str, log: list | None = None,
               validate: bool = True, logging_on: bool = True) -> LoadedFMU:
    """Extract and instantiate an FMI 2.0 co-simulation FMU once (:class:`LoadedFMU`).

    ``validate=False`` skips fmpy's checks of the model description and ``logging_on=False``
    asks the FMU to log errors only (for the evaluation-only containers of
    ``synthesis.fmi.container_loop``: their parameters carry no start value, and a container
    logging on reports every call of its components)."""
    path = require_fmu(path)
    md = read_model_description(str(path), validate=validate)
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise FMUError(f"{path}: need an FMI 2.0 co-simulation FMU, got FMI {md.fmiVersion} "
                       f"{'co-simulation' if md.coSimulation else 'model exchange only'}")
    unzipdir = extract(str(path))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance_name)

    def logger(component, instance, status, category, message):
        if log is not None:
            log.append(message.decode(errors="replace") if message else "")

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    slave.instantiate(callbacks=callbacks, loggingOn=logging_on)
    _release_pythonfmu_state(slave.dll)
    return LoadedFMU(slave, md, unzipdir, log, callbacks)


#: The pythonfmu binaries loaded as they are in this process (paths), each released at exit.
_PYTHONFMU_BINARIES: set = set()


def _release_pythonfmu_state(dll) -> None:
    """Have ``dll``'s ``finalizePythonInterpreter`` called at this interpreter's exit, if it
    is a pythonfmu binary (see the module docstring; other libraries have no such function)."""
    if not hasattr(dll, "finalizePythonInterpreter") or dll._name in _PYTHONFMU_BINARIES:
        return
    if not _PYTHONFMU_BINARIES:
        atexit.register(_release_all)
    _PYTHONFMU_BINARIES.add(dll._name)


def _release_all() -> None:
    """At exit: ``finalizePythonInterpreter`` of each pythonfmu binary still loaded (one the
    host unloaded is not called; RTLD_NOLOAD finds a loaded library without loading it)."""
    for name in sorted(_PYTHONFMU_BINARIES):
        try:
            lib = ctypes.CDLL(name, mode=os.RTLD_NOLOAD)
        except OSError:
            continue
        lib.finalizePythonInterpreter.restype = None
        lib.finalizePythonInterpreter()
    _PYTHONFMU_BINARIES.clear()


class CFunctions:
    """``functions["fmi2DoStep"]``: the C function of a loaded FMU's shared library (fmpy has
    set its argument and result types when it loaded the library)."""

    def __init__(self, dll):
        self._dll = dll

    def __getitem__(self, name):
        return getattr(self._dll, name)


def not_an_output(md, name: str) -> str:
    """The error for a stop condition on ``name``, not an output of ``md``: its outputs."""
    outs = ", ".join(sorted(v.name for v in md.modelVariables if v.causality == "output"))
    return f"{md.modelName}: stop condition {name!r} is not an output (its outputs: {outs})"
