"""S1 model-error families as data: what a guidance is judged against.

A family is a box of plant parameters around the scenario's nominal values plus ranges of the
sensing errors (accelerometer noise and bias, which the guidance's estimator simulates); a
sample set of a family is a Latin hypercube over that box (stratified in every parameter),
seeded.  :data:`FAMILIES` [choice]:

* ``spec`` -- the specified dispersion: rho0 +-15 %, m +-5 %, V0 +-50 m/s, beta0 +-0.03 deg;
* ``scale-height`` -- the specified dispersion and a density-profile shape error: the inverse
  scale height lam +-5 % (the density at 40 km then differs from the model's by up to e^(0.27) when
  its sea-level value is right), which no constant drag factor describes;
* ``accel`` -- the specified dispersion and accelerometer errors: white noise of 0-0.05 m/s2
  and a bias of +-0.02 m/s2 (2 mg; the drag at entry is 0.065 m/s2);
* ``entry`` -- entry-state errors beyond the dispersion box: V0 +-100 m/s, beta0 +-0.06 deg
  (twice the dispersion half-widths), with its rho0, m;
* ``all`` -- every error at once (scale height, accelerometer, the wide entry box).

``descent-fmus reentry robustness --errors FAMILY...`` flies each family's held-out set.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.problems.dispersion import Box

__all__ = ["ErrorFamily", "Sample", "FAMILIES", "family", "family_samples", "DISPERSION"]

DISPERSION_RELATIVE = {"rho0": 0.15, "m": 0.05}
DISPERSION_ABSOLUTE = {"V0": 50.0, "beta0": math.radians(0.03)}


@dataclass(frozen=True)
class ErrorFamily:
    """A box of plant parameters (relative and absolute half-widths around the scenario's
    values) and uniform ranges of the sensing errors (controller parameters)."""

    name: str
    description: str
    relative: dict = field(default_factory=lambda: dict(DISPERSION_RELATIVE))
    absolute: dict = field(default_factory=lambda: dict(DISPERSION_ABSOLUTE))
    sensing: dict = field(default_factory=dict)      # name: (lo, hi)

    def box(self, base: ReentryParams = ReentryParams()) -> Box:
        """The family's box around ``base`` (plant parameters, then sensing errors)."""
        return Box.around(asdict(base), relative=self.relative, absolute=self.absolute,
                          bounds=self.sensing)


@dataclass(frozen=True)
class Sample:
    """One sample: the true plant and the sensing errors of the guidance's estimator."""

    plant: ReentryParams
    sensing: dict

    def key(self) -> tuple:
        return tuple(sorted(asdict(self.plant).items())) + tuple(sorted(self.sensing.items()))


_ACCEL = {"noise": (0.0, 0.05), "bias": (-0.02, 0.02)}
DISPERSION = ErrorFamily("spec", "dispersion: rho0 +-15 %, m +-5 %, V0 +-50 m/s, "
                         "beta0 +-0.03 deg")
FAMILIES = {f.name: f for f in (
    DISPERSION,
    ErrorFamily("scale-height", "dispersion + density scale-height error: lam +-5 %",
                relative=dict(DISPERSION_RELATIVE, lam=0.05)),
    ErrorFamily("accel", "dispersion + accelerometer noise 0-0.05 m/s2 and bias "
                "+-0.02 m/s2", sensing=dict(_ACCEL)),
    ErrorFamily("entry", "entry errors beyond the dispersion: V0 +-100 m/s, beta0 +-0.06 deg "
                "(rho0 +-15 %, m +-5 %)", absolute={"V0": 100.0, "beta0": math.radians(0.06)}),
    ErrorFamily("all", "every error: lam +-5 %, accelerometer noise and bias, V0 +-100 m/s, "
                "beta0 +-0.06 deg, rho0 +-15 %, m +-5 %",
                relative=dict(DISPERSION_RELATIVE, lam=0.05),
                absolute={"V0": 100.0, "beta0": math.radians(0.06)}, sensing=dict(_ACCEL)),
)}


def family(name: str) -> ErrorFamily:
    """The family ``name``; ValueError with the choices otherwise."""
    try:
        return FAMILIES[name]
    except KeyError:
        raise ValueError(f"unknown error family {name!r}; choose from "
                         f"{', '.join(FAMILIES)}") from None


def family_samples(name: str, n: int, seed: int, base: ReentryParams = ReentryParams(),
                   method: str = "lhs") -> list:
    """``n`` seeded :class:`Sample` of the family ``name`` (Latin hypercube by default; the
    nominal point is not among them).  A sample with noise gets its own noise seed."""
    fam = family(name)
    sensing_names = set(fam.sensing)
    out = []
    for k, point in enumerate(fam.box(base).sample(n, seed, method=method)):
        sensing = {s: point.pop(s) for s in list(point) if s in sensing_names}
        if sensing.get("noise", 0.0) > 0.0:
            sensing["noise_seed"] = 1000 * seed + k
        out.append(Sample(base.with_(**point), sensing))
    return out
