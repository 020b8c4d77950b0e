"""Work around pythonfmu 0.7's reference counting (two places).

1. Instantiation.  To find the slave class, pythonfmu 0.7 imports the FMU's entry module,
   executes its code once more in the module's namespace and then releases one reference to
   that namespace (a borrowed reference it never took).  An entry module that defines the class
   itself survives a few instantiations on the references its functions hold; the short entry
   modules of this project (``from ... import Class``) would lose their namespace on the second
   instance in a process.  :func:`balance_namespace`, called by the entry module, takes one
   reference each time the module's code runs, which is exactly what pythonfmu releases.

2. A slave callback that raises.

When a Python callback of a pythonfmu FMU raises (e.g. ``exit_initialization_mode`` rejecting a
parameter, which is how an FMU of this project reports fmi2Error), the C++ wrapper
(``PySlaveInstance::handle_py_exception``) calls ``cleanPyObject()``: it releases its references
to the slave class, the slave instance and its log queue -- and releases them *again* on the
following ``fmi2Reset`` / ``fmi2FreeInstance``, since the pointers are not cleared.  The counts
then go negative and the host process crashes later, typically in the garbage collector
(reproduced: an error in ``exitInitializationMode``, then ``freeInstance``, then ``gc.collect()``
-> segmentation fault, with any pythonfmu FMU of this project).

:func:`keep_refs_on_error` wraps a slave method so that, when it raises, one extra reference to
each of the three objects is taken before the exception reaches the wrapper: the wrapper's extra
release is balanced and the FMU can be reset or freed safely.
"""
from __future__ import annotations

import ctypes
import functools

__all__ = ["keep_refs_on_error", "GUARDED_METHODS", "balance_namespace"]

#: Slave methods that pythonfmu calls from C++ and that may raise (SlaveBase wraps them all).
GUARDED_METHODS = ("setup_experiment", "enter_initialization_mode", "exit_initialization_mode",
                   "do_step", "terminate", "reset")

_incref = ctypes.pythonapi.Py_IncRef
_incref.argtypes = [ctypes.py_object]
_incref.restype = None


def balance_namespace(namespace: dict) -> None:
    """Take one reference to an FMU entry module's namespace (see the module docstring, 1)."""
    namespace.setdefault("_pythonfmu_references", []).append(namespace)


def keep_refs_on_error(method):
    """Decorator for an ``Fmi2Slave`` method that may raise (see the module docstring)."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except BaseException as exc:
            # once per exception, also when nested wrapped methods (super() calls) re-raise it
            if not getattr(exc, "_descent_refs_kept", False):
                for obj in (type(self), self, self._get_log_queue()):
                    _incref(obj)
                try:
                    exc._descent_refs_kept = True
                except AttributeError:
                    pass
            raise

    return wrapper
