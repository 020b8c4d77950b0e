#!/usr/bin/env python
"""Make the S2 figures of the docs (every run through the FMUs) and print their numbers.

* ``docs/figures/mars_alpha.png`` -- alpha(t) without control, with the law (consistent root) and with
  the paper's printed root; u(t) (the paper's figs. 1-2 on one figure).
* ``docs/figures/mars_6dof.png`` -- the averaged model against the rigid-body plant: (a) no control,
  (b) the law fed the omega_1-mode amplitude/phase and fed the instantaneous angles,
  (c) the end-of-descent error of the averaged model against alpha0.

    python docs/make_mars_figures.py [--fmus DIR] [--out DIR]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.plotting import save_figure
from descent_fmus.synthesis.systems.mars.flight import (ALPHA_TARGET, RECORD_6DOF, fly_set,
                                                        load_loop, plot_alpha)
from descent_fmus.synthesis.systems.mars.wiring import WIRING_6DOF, WIRING_6DOF_INSTANT

DOCS = Path(__file__).resolve().parent / "figures"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ or $DESCENT_FMUS_DIR)")
    ap.add_argument("--out", type=Path, default=DOCS, help="folder of the figures (docs/figures/)")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib.pyplot as plt

    runs = fly_set(args.fmus, formulas=("consistent", "paper"))
    plot_alpha(runs, args.out / "mars_alpha.png")
    for r in runs:
        print(f"{r.label:22s} alpha_end = {r.alpha_end:.3e} rad")
    print(f"ratio no control / law = {runs[0].alpha_end / runs[1].alpha_end:.3g}")

    ctrl, none, paper = runs[1].result, runs[0].result, runs[2].result
    with load_loop(args.fmus, WIRING_6DOF, RECORD_6DOF) as loop:
        r6_none = loop.run(controller_values={"u_max": 0.0}, record=True)
        r6_m1 = loop.run(record=True)
        sweep = []
        for a0 in (0.05, 0.1, 0.2, 0.35, 0.5, 0.8, 1.2):
            end6 = loop.run({"alpha0": a0}, {"u_max": 0.0}).final["alpha"]
            sweep.append((a0, end6))
    with load_loop(args.fmus) as loop:
        sweep = [(a0, e6, loop.run({"alpha0": a0}, {"u_max": 0.0}).final["alpha"])
                 for a0, e6 in sweep]
    with load_loop(args.fmus, WIRING_6DOF_INSTANT, RECORD_6DOF) as loop:
        r6_inst = loop.run(record=True)

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    ax[0].plot(none.time, none["alpha"], label="averaged model")
    ax[0].plot(r6_none.time, r6_none["alpha"], "--", label="rigid body: alpha")
    ax[0].set(title="(a) no control", xlabel="t [s]", ylabel="alpha [rad]")
    ax[1].semilogy(ctrl.time, ctrl["alpha"], "k", label="averaged model")
    ax[1].semilogy(r6_m1.time, r6_m1["alpha"], label="rigid body, law fed mode 1: alpha")
    ax[1].semilogy(r6_m1.time, r6_m1["alpha_m1"], ":", label="  ... its omega_1 mode")
    ax[1].semilogy(r6_m1.time, r6_m1["alpha_m2"], ":", label="  ... its omega_2 mode")
    ax[1].semilogy(r6_inst.time, r6_inst["alpha"], label="rigid body, law fed alpha, theta")
    ax[1].axhline(ALPHA_TARGET, color="grey", ls=":", lw=0.8)
    ax[1].set(title="(b) with the law", xlabel="t [s]", ylabel="alpha [rad]", ylim=(1e-8, 2))
    a0s = np.array([s[0] for s in sweep])
    err = np.array([s[1] / s[2] - 1.0 for s in sweep])
    ax[2].loglog(a0s, np.abs(err), "o-")
    ax[2].set(title="(c) no control: rigid / averaged - 1 at h_end",
              xlabel="alpha0 [rad]", ylabel="relative difference")
    for a in ax[:2]:
        a.legend(fontsize=7)
    save_figure(fig, args.out / "mars_6dof.png", ax, dpi=80)

    a_avg = np.interp(r6_none.time, none.time, none["alpha"])
    print(f"no control: max |alpha_m1(rigid)/alpha(avg) - 1| = "
          f"{np.max(np.abs(r6_none['alpha_m1'] / a_avg - 1)):.2e}, "
          f"alpha_end rigid {r6_none.final['alpha']:.4f} vs averaged {none.final['alpha']:.4f}")
    print(f"law fed mode 1: alpha_end = {r6_m1.final['alpha']:.3e} (omega_1 mode "
          f"{r6_m1.final['alpha_m1']:.2e}, omega_2 mode {r6_m1.final['alpha_m2']:.2e})")
    a_ctl = np.interp(r6_m1.time, ctrl.time, ctrl["alpha"])
    big = a_ctl > 1e-3
    print(f"law fed mode 1: max |alpha_m1/alpha(avg) - 1| while alpha(avg) > 1e-3: "
          f"{np.max(np.abs(r6_m1['alpha_m1'][big] / a_ctl[big] - 1)):.3f}")
    cross = r6_inst.time[np.argmax(r6_inst["alpha_m2"] > r6_inst["alpha_m1"])]
    print(f"law fed alpha, theta: alpha_end = {r6_inst.final['alpha']:.3f} rad; the omega_2 mode "
          f"exceeds the omega_1 mode from t = {cross:.1f} s")
    for a0, e6, ea in sweep:
        print(f"alpha0 = {a0:4.2f}: alpha_end rigid {e6:.4f}, averaged {ea:.4f}, "
              f"difference {e6 / ea - 1:+.2%}")
    print(f"paper root: max |u| = {np.max(np.abs(paper['ctrl.u'])):.1e}")


if __name__ == "__main__":
    main()
