#!/usr/bin/env python
"""Make the S1 robust-guidance figure and numbers of the docs (every flight through the FMUs).

From the runs of ``synthesize reentry-sensed`` (law of y1, y2, y3), ``synthesize
reentry-sensed-y12`` (y1, y2 only) and, if given, ``synthesize reentry-sensed --method
cma-polynomial`` (the CMA-ES baseline), the robust law of each (``sensed.best_row``: lowest J2
with median J1 < 9.0 and the nominal flight within 1 km) and, if given, the guided law of a
``synthesize reentry-guided`` run (lowest median J1 with median miss < 1 km) is flown over the
held-out set (200 uniform samples, seed 7, disjoint from the synthesis set) of both scenarios
with the paper's basic law, the nominal synthesised law (``nominal_law.json``) alone and with
the on-board correction, the NPC guidance, the best open-loop program of each scenario flown
blind and the oracle bound.  Writes

* ``docs/figures/reentry_robust.png`` -- miss CDFs against the oracle, J1 boxplots;
* ``docs/figures/reentry_robust.json`` -- the table's numbers;
* ``synthesis/systems/reentry/sensed_law.json`` -- the robust law (the default law of the built
  ``ReentrySensedClosedLoop.fmu``; the tests fly it);
* ``synthesis/systems/reentry/guided_law.json`` -- the guided law (the default law of
  ``ReentryGuidedClosedLoop.fmu``), with ``--guided``; the guided law is also flown with the
  load gate ``--gate`` (``correction_gate``).

    python docs/make_reentry_robust_figures.py SENSED_RUN Y12_RUN [--cma CMA_RUN]
        [--guided GUIDED_RUN] [--gate 20] [--samples 200] [--seed 7] [--fmus DIR] [--programs DIR]

``families`` makes the figure of the model-error families instead (:func:`families_main`): the
committed guided law re-planned (the recommended configuration), with the load gate, plain,
and the NPC over each family's held-out set (200 Latin-hypercube samples, seed 7), beside the
oracle bound and the load oracle; ``docs/figures/reentry_families.png`` and ``.json``
(``--scenario second``: the families around the second scenario's entry,
``reentry_families_second.*``).  Each option's flights are kept in ``--out`` (resumed there),
the limits in the cache folder.

    python docs/make_reentry_robust_figures.py families [--errors spec scale-height]
        [--samples 200] [--seed 7] [--scenario default|second] [--options replan gate20 ...]
        [--load-oracle N] [--out DIR] [--fmus DIR]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from descent_fmus.models.reentry import SECOND_SCENARIO, ReentryParams
from descent_fmus.synthesis.cli.common import json_safe
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.paths import fmu_dir
from descent_fmus.synthesis.systems.reentry.bound import Program, optimize_open_loop
from descent_fmus.synthesis.systems.reentry.guidance import (DEFAULT_LAW_FILE, GUIDED_LAW_FILE,
                                                             NOMINAL_LAW_FILE)
from descent_fmus.synthesis.systems.reentry.laws import as_guided
from descent_fmus.synthesis.systems.reentry.objectives import J1_LIMIT
from descent_fmus.synthesis.systems.reentry.reports import best_guided_row, best_row
from descent_fmus.synthesis.systems.reentry.robust_study import (plot_robust_study,
                                                                  robust_study, table_lines)

DOCS = ROOT / "docs" / "figures"
#: The load gate of the guided law's extra row [choice] (docs/systems/reentry.md, "S1 load gate").
GATE = 20.0


def best_law(run: Path) -> tuple[NetworkOperator, dict]:
    """The run's robust law (sensed.best_row: lowest J2 with median J1 < 9.0 and the nominal
    flight within 1 km)."""
    row = best_row(json.loads((run / "pareto.json").read_text()))
    if row is None:
        raise SystemExit(f"{run}: no law with median J1 < {J1_LIMIT}")
    return NetworkOperator.from_dict(row["law"]), row


def best_guided_law(run: Path) -> tuple[NetworkOperator, dict]:
    """The guided run's law (lowest median J1 with median miss < 1 km, nominal within 1 km)."""
    row = best_guided_row(json.loads((run / "pareto.json").read_text()))
    if row is None:
        raise SystemExit(f"{run}: no law with median miss < 1 km")
    return NetworkOperator.from_dict(row["law"]), row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sensed_run", type=Path)
    ap.add_argument("y12_run", type=Path)
    ap.add_argument("--cma", type=Path, help="run of --method cma-polynomial")
    ap.add_argument("--guided", type=Path, help="run of synthesize reentry-guided")
    ap.add_argument("--gate", type=float, default=GATE, metavar="G",
                    help=f"load gate [g] of the guided law's extra row (default {GATE:g}; "
                         "0 = no extra row)")
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    ap.add_argument("--programs", type=Path, metavar="DIR",
                    help="folder caching the best open-loop programs of both scenarios "
                         "(open_loop_default.json, open_loop_second.json)")
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")

    laws, rows = {}, {}
    law, rows["sensed"] = best_law(args.sensed_run)
    law.save(DEFAULT_LAW_FILE)
    laws["synthesised, y1 y2 y3 (sensed)"] = law
    laws["synthesised, y1 y2 (same objective)"], rows["y12"] = best_law(args.y12_run)
    if args.cma:
        laws["CMA-ES polynomial, y1 y2 y3"], rows["cma"] = best_law(args.cma)
    if args.guided:
        law, rows["guided"] = best_guided_law(args.guided)
        law.save(GUIDED_LAW_FILE)
        laws["synthesised guided law (y1 y2 y3 c + correction)"] = law
        if args.gate > 0.0:
            laws[f"synthesised guided law, load gate {args.gate:g} g"] = \
                (law, {"correction_gate": args.gate})
    nominal = NetworkOperator.load(NOMINAL_LAW_FILE)
    laws["nominal synthesised law"] = nominal
    laws["nominal synthesised law + correction c"] = as_guided(nominal)
    programs = {}
    for name, params in (("default", ReentryParams()), ("second", SECOND_SCENARIO)):
        cached = args.programs / f"open_loop_{name}.json" if args.programs else None
        if cached is not None and cached.exists():
            programs[name] = Program.load(cached)
            continue
        programs[name] = optimize_open_loop(params)
        if cached is not None:
            cached.parent.mkdir(parents=True, exist_ok=True)
            programs[name].save(cached)
    study = robust_study(laws, args.samples, args.seed, args.fmus, ("default", "second"),
                         programs=programs)
    plot_robust_study(study, DOCS / "reentry_robust.png")
    summary = {k: v for k, v in study.items() if k != "scenarios"}
    summary["scenarios"] = {n: {"stats": sc["stats"]} for n, sc in study["scenarios"].items()}
    summary["laws"] = {k: {"formula": r["formula"], "readable": r.get("readable"),
                           "J1": r["J1"], "J2": r["J2"]} for k, r in rows.items()}
    (DOCS / "reentry_robust.json").write_text(json.dumps(json_safe(summary), indent=1))
    print("\n".join(table_lines(study)))


#: The options of the families' figure: name -> controller parameters of the guided law (None:
#: the NPC).  The first is the recommended configuration (docs/systems/reentry.md).
FAMILY_OPTIONS = {"replan": ("guided law, re-planned (recommended)", {"replan": 1}),
                  "gate20": (f"guided law, load gate {GATE:g} g", {"correction_gate": GATE}),
                  "ungated": ("guided law, one correction c", {}),
                  "npc": ("NPC guidance", None)}


def families_main(argv=None):
    """The model-error families' figure (module docstring)."""
    import sys

    import numpy as np

    from descent_fmus.synthesis.systems.reentry.error_families import FAMILIES
    from descent_fmus.synthesis.systems.reentry.family_study import family_study
    from descent_fmus.synthesis.systems.reentry.guidance import default_guided_law
    from descent_fmus.synthesis.systems.reentry.robust_study import SCENARIOS
    ap = argparse.ArgumentParser(description="S1 guidance over the model-error families")
    ap.add_argument("--errors", nargs="+", default=["spec", "scale-height"], choices=FAMILIES)
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--scenario", choices=tuple(SCENARIOS), default="default",
                    help="entry conditions the families are drawn around (second: "
                         "reentry_families_second.png and .json)")
    ap.add_argument("--options", nargs="+", choices=tuple(FAMILY_OPTIONS),
                    default=list(FAMILY_OPTIONS), help="guidance options flown (default all)")
    ap.add_argument("--load-oracle", type=int, default=None, metavar="N",
                    help="compute the load oracle of the first N samples (default all; ~30 s "
                         "a reachable sample); the others use what the cache holds")
    ap.add_argument("--out", type=Path, default=Path("runs/reentry-families"))
    ap.add_argument("--fmus", type=Path, default=fmu_dir())
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    law = default_guided_law()
    laws = {label: (law, params) for key, (label, params) in FAMILY_OPTIONS.items()
            if key in args.options and params is not None}
    found = family_study(laws, args.errors, args.samples, args.seed, args.fmus,
                         npc="npc" in args.options, load_oracle=args.load_oracle, basic=False,
                         base=SCENARIOS[args.scenario], flown=args.out / args.scenario,
                         progress=lambda fam, n: print(f"{fam}: {n} flown", file=sys.stderr))
    study = {**found, "scenario": args.scenario, "scenarios": {}}
    for fam, sc in found["scenarios"].items():
        loaded = [k for k, r in enumerate(sc["limits"]) if "J1_load" in r]
        # the options' median J1 on the samples that have a load oracle, beside its median
        sc["stats_load_subset"] = {n: float(np.median([rows[k]["J1"] for k in loaded]))
                                   for n, rows in sc["results"].items()} if loaded else {}
        study["scenarios"][fam if args.scenario == "default" else
                           f"{args.scenario} scenario, {fam}"] = sc
    stem = "reentry_families" + ("" if args.scenario == "default" else f"_{args.scenario}")
    plot_robust_study(study, DOCS / f"{stem}.png")
    summary = {k: v for k, v in study.items() if k != "scenarios"}
    summary["scenarios"] = {n: {"stats": sc["stats"],
                                "J1_median_on_load_oracle_samples": sc["stats_load_subset"]}
                            for n, sc in study["scenarios"].items()}
    (DOCS / f"{stem}.json").write_text(json.dumps(json_safe(summary), indent=1))
    print("\n".join(table_lines(study)))
    for n, sc in study["scenarios"].items():
        computed = sum("J1_load" in r for r in sc["limits"])
        print(f"{n}: median J1 on the {computed} samples with a load oracle: "
              f"{sc['stats_load_subset']}")


if __name__ == "__main__":
    import sys
    if sys.argv[1:2] == ["families"]:
        families_main(sys.argv[2:])
    else:
        main()
