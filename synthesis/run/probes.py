"""The equivalence keys' law values through the native interpreter: many probe points, one call.

The evaluator's equivalence test (:mod:`synthesis.run.evaluation`) evaluates every new law on
a few dozen fixed input points; in Python (:meth:`NetworkOperator.raw_points`) that was the
largest share of the search's main process.  Where the flights run on the native twins, the
controller twin's own C interpreter (``no_interp.c`` with its generated operations, read from
the twin FMU's ``sources/``) is compiled once into a small library (the cache folder, keyed by
its sources: :func:`~synthesis.fmi.native.builders.build.cached_library`) with one exported
function that compiles a law's matrix and evaluates it at every point.  It is the interpreter
the flights run, built with the same flags (``-ffp-contract=off``), which gives the Python
interpreter's values bit for bit (``tests/fmi/native``); the first laws of a run are evaluated
both ways all the same, and a difference sends the run back to the Python route.

:func:`native_prober` returns None (Python route) without a twin, a compiler or the sources.
"""
from __future__ import annotations

import ctypes
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from descent_fmus.models.controllers.network_operator import L_MAX, NU_MAX

__all__ = ["NativeProber", "native_prober"]

#: Files of a controller twin's ``sources/`` the prober compiles.
SOURCES = ("no_interp.c", "no_interp.h", "no_operations.h", "model_config.h")
#: Laws of a run checked against the Python route before the native one is trusted alone.
CHECKED_LAWS = 64

_WRAPPER = r"""/* probe_eval.c -- a law's values at many points: no_compile once, no_evaluate per point */
#include "no_interp.h"

__attribute__((visibility("default")))
int no_probe_eval(const int *psi, int nx, int nq, const int *out, int nu,
                  const double *sources, int npts, double *values)
{
    NOProgram p;
    char msg[256];
    int k;
    if (no_compile(&p, psi, nx, nq, out, nu, msg, sizeof msg) != NULL)
        return -1;
    for (k = 0; k < npts; k++)
        no_evaluate(&p, sources + (size_t)k * (size_t)(nx + nq), values + (size_t)k * nu);
    return 0;
}

__attribute__((visibility("default")))
int no_probe_lmax(void) { return NO_L_MAX; }
"""

_UPPER = np.triu_indices(L_MAX)        # the twin's psi order: the upper triangle row by row


#: [choice] The twin's matrices of the last structures probed (the search probes many parameter
#: vectors per structure: a CMA-ES generation, children that share a form)
MATRIX_CACHE = 4096
_MATRICES: dict = {}


def _twin_matrix(psi: np.ndarray) -> np.ndarray:
    """A law's matrix as the twin holds it (``L_MAX`` nodes, the upper triangle row by row)."""
    key = (psi.shape, psi.tobytes())
    got = _MATRICES.get(key)
    if got is None:
        full = np.zeros((L_MAX, L_MAX), np.intc)
        full[:psi.shape[0], :psi.shape[1]] = psi
        got = np.ascontiguousarray(full[_UPPER])
        if len(_MATRICES) >= MATRIX_CACHE:
            del _MATRICES[next(iter(_MATRICES))]          # the oldest entry
        _MATRICES[key] = got
    return got


class NativeProber:
    """``values(law, points)``: :meth:`NetworkOperator.raw_points` flattened, through C."""

    def __init__(self, library: Path):
        dll = ctypes.CDLL(str(library))
        if dll.no_probe_lmax() != L_MAX:
            raise OSError(f"the twin's interpreter holds {dll.no_probe_lmax()} nodes, "
                          f"not {L_MAX}")
        # [choice] plain addresses of arrays made contiguous here: numpy's checked pointer
        # types cost more than the C evaluation of a law at 16 points
        p, i = ctypes.c_void_p, ctypes.c_int
        dll.no_probe_eval.restype = i
        dll.no_probe_eval.argtypes = [p, i, i, p, i, p, i, p]
        c_eval = dll.no_probe_eval
        self._eval = lambda psi, nx, nq, outputs, nu, src, n, out: c_eval(
            psi.ctypes.data, nx, nq, outputs.ctypes.data, nu, src.ctypes.data, n,
            out.ctypes.data)
        self.checked = 0               # laws compared with the Python route so far
        self.trusted = True
        # [choice] the probe points as a law reads them (scaled by its inputs' scaling) and
        # its output nodes as C integers, kept by their content: the laws of a run share them
        self._scaled: dict = {}
        self._outputs: dict = {}

    def _points(self, law, points):
        """``points`` as the law's nodes read them (raw: ``s * (v - o)`` per input, the same
        IEEE steps), or None when they do not fit the law's inputs."""
        if law._scaled:
            key = (id(points), tuple(law.input_scale), tuple(law.input_offset))
            got = self._scaled.get(key)
            if got is not None and got[0] is points:
                return got[1]
        x = np.asarray(points, np.float64)
        if x.ndim != 2 or x.shape[1] != law.nx:
            return None
        if law._scaled:
            x = np.asarray(law.input_scale) * (x - np.asarray(law.input_offset))
            if len(self._scaled) >= 64:
                self._scaled.clear()
            self._scaled[key] = (points, x)
        return x

    def values(self, law, points) -> list:
        """The law's unclipped outputs at ``points``, point by point (None: the Python route
        must answer: a law larger than the twin, or one the twin refuses)."""
        if not self.trusted or law.size > L_MAX or len(law.outputs) > NU_MAX \
                or getattr(law, "_program", None) is None:
            return None
        x = self._points(law, points)
        if x is None:
            return None
        src = np.empty((len(x), law.nx + len(law.q)))
        src[:, :law.nx] = x
        src[:, law.nx:] = law.q
        outputs = tuple(law.outputs)
        outs = self._outputs.get(outputs)
        if outs is None:
            if len(self._outputs) >= 64:
                self._outputs.clear()
            outs = self._outputs[outputs] = np.array(outputs, np.intc)
        nu = len(outputs)
        out = np.empty(len(x) * nu)
        if self._eval(_twin_matrix(law.psi), law.nx, len(law.q), outs, nu, src, len(x),
                      out) != 0:
            return None
        got = out.tolist()
        if self.checked < CHECKED_LAWS:
            self.checked += 1
            want = [float(v) for row in law.raw_points(points) for v in row]
            if [v.hex() for v in got] != [v.hex() for v in want]:
                self.trusted = False
                return want
        return got


def native_prober(problem, fmus) -> NativeProber | None:
    """The native prober of a problem flown on native twins (``fmus``: plant and controller),
    or None (the Python route)."""
    try:
        from descent_fmus.synthesis.fmi.native.builders.build import cached_library
        from descent_fmus.synthesis.fmi.native_loop import native_fmus
        twins = native_fmus(problem.wiring, *fmus)
        if twins is None:
            return None
        with zipfile.ZipFile(twins[1]) as z, tempfile.TemporaryDirectory() as tmp:
            names = set(z.namelist())
            if any(f"sources/{f}" not in names for f in SOURCES):
                return None
            for f in SOURCES:
                (Path(tmp) / f).write_bytes(z.read(f"sources/{f}"))
            (Path(tmp) / "probe_eval.c").write_text(_WRAPPER)
            paths = [Path(tmp) / f for f in ("probe_eval.c", "no_interp.c")]
            lib = cached_library("probe-keys", paths, [Path(tmp) / f for f in SOURCES[1:]])
        return NativeProber(lib)
    except Exception:     # no compiler, a build error, an unreadable twin: the Python route
        return None
