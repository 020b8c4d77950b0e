"""S5 flights through the FMUs: a law on the initial-state set and on a seeded dispersion.

Every number here comes from the closed loop of the ``LunarDescent`` plant FMU and the generic
``NetworkOperatorController`` FMU (synthesis.cosim), the same path as the GA's evaluator.

References
----------
Seed 004: A.I. Diveev et al., Vestnik MGTU im. Baumana, ser. Priborostroenie, 2013, no. 4;
dispersion (thrust +-3 %, specific impulse +-1 %): issue 6 / SPEC S5 [choice].
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.cosim import ClosedLoop
from descent_fmus.synthesis.systems.lunar_descent.problems import (INITIAL_SET, WIRING, initial_states, objectives,
                                               per_state)

__all__ = ["DISPERSION", "dispersion_states", "fly_set", "study", "front_comparison"]

#: Dispersion of the robustness study [choice]: initial states uniform over the whole ranges
#: theta0 in [89, 91] deg, h0 in [17.5, 18.5] km; thrust factor k_P in [0.97, 1.03]; specific
#: impulse P_ud in 319 s +- 1 %.
DISPERSION = {"theta0": (math.radians(89.0), math.radians(91.0)), "h0": (17_500.0, 18_500.0),
              "k_P": (0.97, 1.03), "P_ud": (319.0 * 0.99, 319.0 * 1.01)}


def dispersion_states(samples: int, seed: int) -> list:
    """``samples`` plant start-value dicts drawn uniformly from :data:`DISPERSION`."""
    rng = np.random.default_rng(seed)
    return [{k: float(rng.uniform(lo, hi)) for k, (lo, hi) in DISPERSION.items()}
            for _ in range(samples)]


def fly_set(loop: ClosedLoop, law, states, record: bool = False) -> list:
    """Per-state results (``per_state`` fields + the start values) of one law over ``states``;
    with ``record`` each row also carries the trajectory (t, V, h)."""
    sv = law.start_values()
    rows = []
    for s in states:
        res = loop.run(plant_values=s, controller_values=sv, record=record)
        row = dict(per_state(res.final), **s)
        if record:
            row["trace"] = {"t": res.time.tolist(), "V": res["V"].tolist(),
                            "h": res["h"].tolist()}
        rows.append(row)
    return rows


def _stats(rows) -> dict:
    dh = np.array([abs(r["h"] - 2000.0) for r in rows])
    dv = np.array([abs(r["V"] - 50.0) for r in rows])
    fuel = np.array([r["fuel"] for r in rows])
    return {"n": len(rows), "in_box": int(sum(r["in_box"] for r in rows)),
            "crashed": int(sum(r["crashed"] for r in rows)),
            "h_min": float(min(r["h_min"] for r in rows)),
            "dh_median": float(np.median(dh)), "dh_p95": float(np.percentile(dh, 95)),
            "dh_max": float(dh.max()), "dV_median": float(np.median(dv)),
            "dV_max": float(dv.max()), "fuel_mean": float(fuel.mean()),
            "fuel_max": float(fuel.max())}


def study(laws: dict, fmu_dir, samples: int = 100, seed: int = 7, record: bool = False) -> dict:
    """Each law on the initial-state set (J1, J2, per-state rows) and on the dispersion.

    Parameters
    ----------
    laws : dict of str -> NetworkOperator
    fmu_dir : path-like
        Folder with ``LunarDescent.fmu`` and ``NetworkOperatorController.fmu``.
    samples, seed : int
        Size and seed of the dispersion set (:func:`dispersion_states`).
    """
    d = Path(fmu_dir)
    disp = dispersion_states(samples, seed)
    out = {"samples": samples, "seed": seed, "laws": {}}
    with ClosedLoop(WIRING, d / f"{WIRING.plant}.fmu", d / f"{WIRING.controller}.fmu",
                    record=("V", "h")) as loop:
        for name, law in laws.items():
            rows = fly_set(loop, law, initial_states(), record=record)
            finals = [{"V": r["V"], "h": r["h"], "h_min": r["h_min"], "fuel": r["fuel"],
                       "t_end": r["t_end"], "end": 1.0 if r["in_box"] else
                       (2.0 if r["crashed"] else 3.0)} for r in rows]
            (j1, j2), _ = objectives(finals)
            drows = fly_set(loop, law, disp) if samples else []
            out["laws"][name] = {"J1": j1, "J2": j2, "initial_set": _stats(rows),
                                 "rows": rows, "dispersion": _stats(drows) if drows else None,
                                 "dispersion_points": [[r["V"], r["h"], r["in_box"]]
                                                       for r in drows],
                                 "formula": law.formula(6)}
    return out


def front_comparison(front_a, front_b, ref=None) -> dict:
    """Compare two Pareto fronts (arrays of (J1, J2)): hypervolumes w.r.t. ``ref`` (default:
    the worst point of both fronts x 1.1), and how many points of b are dominated by a."""
    from descent_fmus.synthesis.methods.pareto import dominates, hypervolume_2d
    a, b = np.asarray(front_a, float), np.asarray(front_b, float)
    if ref is None:
        ref = np.vstack([a, b]).max(axis=0) * 1.1
    hv_a, hv_b = hypervolume_2d(a, ref), hypervolume_2d(b, ref)
    dominated = sum(any(dominates(p, q) for p in a) for q in b)
    return {"ref": [float(v) for v in ref], "hv_a": hv_a, "hv_b": hv_b,
            "hv_ratio": hv_a / hv_b if hv_b > 0 else math.inf,
            "b_dominated_by_a": int(dominated), "b_size": len(b), "a_size": len(a)}


def initial_set_degrees() -> list:
    """The initial-state set as (theta0 [deg], h0 [m]) for reports."""
    return [(math.degrees(t), h) for t, h in INITIAL_SET]
