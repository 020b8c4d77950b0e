"""S5 flights: a law on the initial-state set and on a seeded dispersion, through the FMUs.

Every number of :func:`study` comes from the closed loop of the ``LunarDescent`` plant FMU and
the generic ``NetworkOperatorController`` FMU (synthesis.fmi.closed_loop), the same path as the GA's
evaluator.  :func:`fly_in_process` flies the same equations in-process (tests, quick scans).

References
----------
A.I. Diveev et al., Vestnik MGTU im. Baumana, ser. Priborostroenie, 2013, no. 4; the
dispersion (thrust +-3 %, specific impulse +-1 %) is our [choice] (models/README.md).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from descent_fmus.models.lunar_descent import DescentParams
from descent_fmus.synthesis.fmi.loop import Loop, open_loop
from descent_fmus.synthesis.problems.dispersion import Box
from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
from descent_fmus.synthesis.systems.lunar_descent.problems import (HF, STEP, VF, WIRING,
                                                                    initial_states, per_state,
                                                                    totals)

__all__ = ["DISPERSION", "dispersion_box", "dispersion_states", "load_loop", "fly_set",
           "fly_in_process", "study", "front_comparison", "plot_study"]

#: Dispersion of the robustness study [choice]: initial states uniform over the whole ranges
#: theta0 in [89, 91] deg, h0 in [17.5, 18.5] km; thrust factor k_P in [0.97, 1.03]; specific
#: impulse P_ud in 319 s +- 1 %.
DISPERSION = {"theta0": (math.radians(89.0), math.radians(91.0)), "h0": (17_500.0, 18_500.0),
              "k_P": (0.97, 1.03), "P_ud": (319.0 * 0.99, 319.0 * 1.01)}


def dispersion_box() -> Box:
    """The dispersion set :data:`DISPERSION` as a :class:`~synthesis.problems.dispersion.Box`."""
    return Box.from_bounds(DISPERSION)


def dispersion_states(samples: int, seed: int) -> list:
    """``samples`` plant start-value dicts drawn uniformly from :data:`DISPERSION` (none if
    ``samples`` is 0)."""
    return dispersion_box().sample(samples, seed) if samples else []


def load_loop(fmu_dir=None, record=("V", "h")) -> Loop:
    """The LunarDescent + NetworkOperatorController closed loop, loaded once (reset per
    flight)."""
    d = Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()
    return open_loop(WIRING, d / f"{WIRING.plant}.fmu", d / f"{WIRING.controller}.fmu",
                     native=False, record=record)


def fly_set(loop: Loop, law, states, record: bool = False) -> list:
    """Per-state results (:func:`per_state` fields + the start values) of one law over
    ``states``; with ``record`` each row also carries the trajectory (t [s], V [m/s], h [m])."""
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


def fly_in_process(law, theta0: float, h0: float, step: float = STEP, dt: float | None = None,
                   trace: list | None = None, **params):
    """Fly a law in-process from (theta0 [rad], h0 [m]) with communication step ``step`` [s]
    (models.lunar_descent.simulate, the same equations as the FMU); returns the finished
    :class:`~models.lunar_descent.DescentIntegrator`."""
    from descent_fmus.models import lunar_descent as ld
    p = ld.DescentParams(theta0=theta0, h0=h0, **params)
    return ld.simulate(p, lambda t, x: law(ld.controller_inputs(x, p)), step=step,
                       dt=ld.DT_INTEGRATION if dt is None else dt, trace=trace)


def _stats(rows) -> dict:
    dh = np.array([abs(r["h"] - HF) for r in rows])
    dv = np.array([abs(r["V"] - VF) for r in rows])
    fuel = np.array([r["fuel"] for r in rows])
    return {"n": len(rows), "in_box": int(sum(r["in_box"] for r in rows)),
            "crashed": int(sum(r["crashed"] for r in rows)),
            "h_min": float(min(r["h_min"] for r in rows)),
            "dh_median": float(np.median(dh)), "dh_p95": float(np.percentile(dh, 95)),
            "dh_max": float(dh.max()), "dV_median": float(np.median(dv)),
            "dV_max": float(dv.max()), "fuel_mean": float(fuel.mean()),
            "fuel_max": float(fuel.max())}


def study(laws: dict, fmu_dir=None, samples: int = 100, seed: int = 7,
          record: bool = False) -> dict:
    """Each law on the initial-state set (J1, J2, per-state rows) and on the dispersion.

    Parameters
    ----------
    laws : dict of str -> NetworkOperator
    fmu_dir : path-like, optional
        Folder with ``LunarDescent.fmu`` and ``NetworkOperatorController.fmu`` (default: the
        package's FMU folder).
    samples, seed : int
        Size and seed of the dispersion set (:func:`dispersion_states`).
    record : bool
        Keep the trajectories of the initial-set flights (``rows[k]["trace"]``, for plots).

    Returns
    -------
    dict
        ``samples``, ``seed`` and per law: ``J1`` [m], ``J2`` [m/s], ``initial_set`` and
        ``dispersion`` statistics, the per-state ``rows``, ``dispersion_points`` (V [m/s],
        h [m], in box) and the law's ``formula``.
    """
    disp = dispersion_states(samples, seed)
    out = {"samples": samples, "seed": seed, "laws": {}}
    with load_loop(fmu_dir) as loop:
        for name, law in laws.items():
            rows = fly_set(loop, law, initial_states(), record=record)
            (j1, j2), _ = totals(rows)
            drows = fly_set(loop, law, disp)
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


def plot_study(res: dict, path) -> Path:
    """PNG: h over V of each law on the initial set (needs ``study(..., record=True)``) and
    |h(tf) - hf| of every dispersion sample."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from descent_fmus.synthesis.plotting import save_figure
    p = DescentParams()
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.8))
    for c, (name, r) in zip(("C0", "C3"), res["laws"].items()):
        for k, row in enumerate(r["rows"]):
            tr = row["trace"]
            ax[0].plot(tr["V"], [h / 1e3 for h in tr["h"]], color=c, lw=1,
                       label=name if k == 0 else None)
    ax[0].set(xlabel="V [m/s]", ylabel="h [km]", xscale="log",
              title=f"initial-state set ({len(initial_states())} states): h over V")
    ax[0].add_patch(Rectangle((p.V_lo, p.h_lo / 1e3), p.V_hi - p.V_lo, (p.h_hi - p.h_lo) / 1e3,
                              fill=False, ec="k", lw=1.2))
    ax[0].legend()
    for c, m, (name, r) in zip(("C0", "C3"), ("o", "s"), res["laws"].items()):
        pts = r["dispersion_points"]
        if not pts:
            continue
        dh = [max(abs(q[1] - HF), 1e-3) for q in pts]
        ok = [q[2] for q in pts]
        k = range(len(pts))
        ax[1].plot([i for i in k if ok[i]], [dh[i] for i in k if ok[i]], m, color=c, ms=3,
                   alpha=0.7, label=f"{name}: in box {sum(ok)}/{len(pts)}")
        if not all(ok):
            ax[1].plot([i for i in k if not ok[i]], [dh[i] for i in k if not ok[i]], "x",
                       color=c, ms=5, label=f"{name}: not in box")
    ax[1].axhline(p.h_hi - HF, color="k", lw=1, ls="--",
                  label=f"box edge (|h - hf| = {p.h_hi - HF:.0f} m)")
    ax[1].set(xlabel="dispersion sample", ylabel="|h(tf) - hf| [m]", yscale="log",
              title=f"dispersion ({res['samples']} samples: theta0, h0, thrust +-3 %, "
                    f"Isp +-1 %)")
    ax[1].legend(fontsize=8)
    return save_figure(fig, path, ax, dpi=110)
