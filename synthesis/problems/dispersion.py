"""Seeded samples of a box of parameter values: the one dispersion sampler of the package.

A :class:`Box` maps parameter names to intervals, written around nominal values either relative
(``rho0`` +-15 %), absolute (``V0`` +-50 m/s) or as bounds (``h0`` in [17.5, 18.5] km).
:meth:`Box.sample` draws seeded points: uniform, Latin hypercube (scipy.stats.qmc) or the
corners, optionally led by the nominal point and followed by the corners::

    box = Box.around({"rho0": 1.22, "V0": 7500.0}, relative={"rho0": 0.15},
                     absolute={"V0": 50.0})
    samples = box.sample(100, seed=7)          # list of {"rho0": ..., "V0": ...}

A uniform draw takes ``rng.uniform(-1, 1, (n, d))`` from ``numpy.random.default_rng(seed)``
(row by row, names in the box's order) and maps each unit value ``r`` to ``c (1 + w r)``
(relative), ``c + w r`` (absolute) or ``lo + (hi - lo) (r + 1) / 2`` (bounds).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from descent_fmus.synthesis.problems.limits import MAX_STATES

__all__ = ["Box", "Interval", "METHODS", "MAX_SAMPLES"]

#: Sampling designs of :meth:`Box.sample`.
#: Most points a box gives (samples, or corners 2^d): the initial states of a problem are flown
#: for every law, so more would make every evaluation, not only the run, unbounded.
MAX_SAMPLES = MAX_STATES
METHODS = ("uniform", "lhs", "corners")


@dataclass(frozen=True)
class Interval:
    """One parameter's interval: ``kind`` "relative" (centre, fraction), "absolute" (centre,
    half-width) or "bounds" (lo, hi)."""

    name: str
    kind: str
    a: float
    b: float

    def __post_init__(self):
        if self.kind not in ("relative", "absolute", "bounds"):
            raise ValueError(f"unknown interval kind {self.kind!r}")
        if not (math.isfinite(self.a) and math.isfinite(self.b)):
            raise ValueError(f"interval of {self.name} must be finite, got ({self.a}, {self.b})")
        if self.kind == "bounds" and self.a > self.b:
            raise ValueError(f"interval of {self.name}: lower bound {self.a} > upper bound "
                             f"{self.b}")
        if self.kind != "bounds" and self.b < 0:
            raise ValueError(f"interval of {self.name}: half-width must be >= 0, got {self.b}")

    def value(self, r: float) -> float:
        """The value at unit coordinate ``r`` in [-1, 1]."""
        if self.kind == "relative":
            return self.a * (1.0 + self.b * r)
        if self.kind == "absolute":
            return self.a + self.b * r
        return self.a + (self.b - self.a) * (r + 1.0) / 2.0

    @property
    def centre(self) -> float:
        return self.a if self.kind != "bounds" else 0.5 * (self.a + self.b)


@dataclass(frozen=True)
class Box:
    """A box of parameter values (see the module docstring)."""

    intervals: tuple

    def __post_init__(self):
        names = [i.name for i in self.intervals]
        if len(set(names)) != len(names):
            raise ValueError(f"a parameter appears twice in the box: {names}")

    @classmethod
    def around(cls, nominal: Mapping[str, float], relative: Mapping[str, float] = None,
               absolute: Mapping[str, float] = None, bounds: Mapping[str, tuple] = None
               ) -> "Box":
        """A box around ``nominal`` values: relative fractions, absolute half-widths, bounds.

        The order of the names is the order of ``relative``, then ``absolute``, then ``bounds``.
        """
        out = []
        for name, w in (relative or {}).items():
            out.append(Interval(name, "relative", float(nominal[name]), float(w)))
        for name, w in (absolute or {}).items():
            out.append(Interval(name, "absolute", float(nominal[name]), float(w)))
        for name, (lo, hi) in (bounds or {}).items():
            out.append(Interval(name, "bounds", float(lo), float(hi)))
        return cls(tuple(out))

    @classmethod
    def from_bounds(cls, bounds: Mapping[str, tuple]) -> "Box":
        """A box given as ``{name: (lo, hi)}``."""
        return cls.around({}, bounds=bounds)

    @property
    def names(self) -> list[str]:
        return [i.name for i in self.intervals]

    def centre(self) -> dict:
        return {i.name: i.centre for i in self.intervals}

    def point(self, r) -> dict:
        """The point at unit coordinates ``r`` (one value in [-1, 1] per interval)."""
        return {i.name: i.value(float(v)) for i, v in zip(self.intervals, r)}

    def sample(self, n: int, seed: int, method: str = "uniform", nominal_first: bool = False,
               corners: bool = False) -> list[dict]:
        """``n`` seeded points of the box.

        Parameters
        ----------
        n : int
            Number of points (>= 1), the nominal point included if ``nominal_first``; for
            ``method="corners"`` the 2^d corners (``n`` is then ignored).
        seed : int
        method : {"uniform", "lhs", "corners"}
        nominal_first : bool
            The first point is the centre of the box (then ``n - 1`` are drawn).
        corners : bool
            Append the 2^d corners after the drawn points.
        """
        if method not in METHODS:
            raise ValueError(f"unknown sampling method {method!r}; choose from "
                             f"{', '.join(METHODS)}")
        if n < 1:
            raise ValueError(f"the number of samples must be >= 1, got {n}")
        d = len(self.intervals)
        count = (2 ** d if method == "corners" else n) + (2 ** d if corners else 0)
        if count > MAX_SAMPLES:
            what = f"{d} dimensions, 2^{d} corners" if method == "corners" or corners else \
                "samples"
            raise ValueError(f"{count} points asked of the box ({what}); the documented "
                             f"maximum is {MAX_SAMPLES}")
        if method == "corners":
            return [self.point(c) for c in itertools.product((-1.0, 1.0), repeat=d)]
        m = n - 1 if nominal_first else n
        rng = np.random.default_rng(seed)
        if method == "uniform":
            units = rng.uniform(-1.0, 1.0, (m, d))
        else:
            from scipy.stats import qmc
            units = 2.0 * qmc.LatinHypercube(d, seed=rng).random(m) - 1.0 if m else \
                np.zeros((0, d))
        out = [self.point([0.0] * d)] if nominal_first else []
        out += [self.point(r) for r in units]
        if corners:
            out += [self.point(c) for c in itertools.product((-1.0, 1.0), repeat=d)]
        return out
