#!/usr/bin/env python
"""Make the S1 figures of the docs from a synthesis run (every flight through the FMUs).

* ``docs/figures/reentry_pareto.png`` -- the run's Pareto front with the basic law and the bound (the
  best open-loop program on the 1 s grid at miss <= 1 km);
* ``docs/figures/reentry_flight.png`` -- the best synthesised law with miss < 1 km against the basic law
  and the bound's program (flown blind through the Reentry FMU): h(L), load(t), u(t);
* ``tests/reference/reentry_best_law.json`` -- that law (the tests fly it through the FMUs).

    python docs/make_reentry_figures.py RUN_DIR [--fmus DIR]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.registry import get_problem
from descent_fmus.synthesis.run.report import plot_front
from descent_fmus.synthesis.systems.reentry.bound import Program, replay_program
from descent_fmus.synthesis.systems.reentry.flight import fly, load_loop
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law
from descent_fmus.synthesis.systems.reentry.objectives import objectives
from descent_fmus.synthesis.systems.reentry.reports import BOUND_FILES

DOCS = ROOT / "docs" / "figures"


class _Rec:
    """A recorded flight as the plots read it: ``time`` and ``rec[name]``."""

    def __init__(self, time, outputs):
        self.time, self.outputs = time, outputs

    def __getitem__(self, name):
        return self.outputs[name]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = json.loads((args.run / "summary.json").read_text())
    best = summary["best_miss_below_1km"]
    rows = json.loads((args.run / "pareto.json").read_text())
    plot_front(get_problem("reentry"), rows, summary, DOCS / "reentry_pareto.png")
    law = NetworkOperator.from_dict(next(r for r in rows if r["k"] == best["k"])["law"])
    ref = ROOT / "tests" / "reference" / "reentry_best_law.json"
    ref.parent.mkdir(exist_ok=True)
    law.save(ref)
    prog = Program.load(args.run / BOUND_FILES[1])
    flights = {}
    with load_loop(args.fmus, record=("h", "L", "load")) as loop:
        for name, lw in (("synthesised law", law), ("basic law (paper q)",
                                                     paper_basic_law())):
            f = fly(lw, loop=loop, record=True)
            flights[name] = (f.result, f.objectives)
    out = replay_program(prog, args.fmus, record=("h", "L", "load"))
    tr = out["trace"]
    flights["bound: best 1 s program, miss <= 1 km"] = (
        _Rec(tr["t"], {"h": tr["h"], "L": tr["L"], "load": tr["load"], "ctrl.u[1]": tr["u"]}),
        objectives(out, ReentryParams()))
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for name, (r, o) in flights.items():
        lab = f"{name}: J1 = {o['J1']:.3f}, miss = {o['J2'] / 1e3:.2f} km"
        ax[0].plot(r["L"] / 1e3, r["h"] / 1e3, label=lab)
        ax[1].plot(r.time, r["load"], label=name)
        ax[2].step(r.time, r["ctrl.u[1]"], where="post", label=name)
    ax[0].set(xlabel="down-range L [km]", ylabel="h [km]", title="trajectory")
    ax[1].set(xlabel="t [s]", ylabel="load (J1 integrand)", title="load")
    ax[2].set(xlabel="t [s]", ylabel="u", title="control")
    ax[0].legend(fontsize=7)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(DOCS / "reentry_flight.png", dpi=100)
    plt.close(fig)
    for name, (_, o) in flights.items():
        print(f"{name:32s} J1 = {o['J1']:.4f}  miss = {o['J2']:.1f} m")


if __name__ == "__main__":
    main()
