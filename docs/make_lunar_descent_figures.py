#!/usr/bin/env python
"""Make the S5 figure of the docs from synthesis runs (every flight through the FMUs).

* ``docs/figures/lunar_descent.png`` -- a synthesised law (row ``--row`` of RUN_DIR/pareto.json) against
  the baseline (the same row of the baseline run, else the basic law): h over V on the initial
  set and the misses of the seeded dispersion (``descent-fmus lunar-descent report``);
* with ``--reference``: ``tests/reference/lunar_descent_law.json`` (that law, which the tests
  fly through the FMUs) and ``lunar_descent_law.meta.json`` (its J1, J2 and where it came from).

    python docs/make_lunar_descent_figures.py RUN_DIR [--baseline-run DIR] [--row K]
        [--samples N] [--seed S] [--fmus DIR] [--out DIR] [--reference]

RUN_DIR is a ``descent-fmus synthesize lunar-descent --out RUN_DIR`` folder (the docs use the
default budget); the baseline run is ``synthesize lunar-descent --lchr 0``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from descent_fmus.synthesis.cli.main import main as cli_main
from descent_fmus.synthesis.methods.law import NetworkOperator

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "tests" / "reference" / "lunar_descent_law.json"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="synthesis run folder (holds pareto.json)")
    ap.add_argument("--baseline-run", type=Path, help="baseline run folder (--lchr 0)")
    ap.add_argument("--row", type=int, default=0, help="Pareto row (default 0, lowest J1)")
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--fmus", type=Path, default=None, help="folder of the built FMUs")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "figures", help="figure folder")
    ap.add_argument("--reference", action="store_true",
                    help="also write the law to tests/reference/lunar_descent_law*.json")
    args = ap.parse_args(argv)
    front = args.run / "pareto.json"
    cmd = ["lunar-descent", "report", "--law", str(front), "--row", str(args.row),
           "--samples", str(args.samples), "--seed", str(args.seed),
           "--plot", str(args.out / "lunar_descent.png")]
    if args.baseline_run:
        base = args.baseline_run / "pareto.json"
        cmd += ["--baseline", str(base), "--front", str(front), "--baseline-front", str(base)]
    if args.fmus:
        cmd += ["--fmus", str(args.fmus)]
    rc = cli_main(cmd)
    if rc or not args.reference:
        return rc
    rows = json.loads(front.read_text())
    row = rows[args.row]
    NetworkOperator.from_dict(row["law"]).save(REFERENCE)
    run = json.loads((args.run / "run.json").read_text())
    ga = run["ga"]
    meta = {"source": f"descent-fmus synthesize lunar-descent (population {ga['population']}, "
                      f"{run['generations']} generations, {ga['crossovers']} crossovers, lchr "
                      f"{ga['lchr']}, epoch {ga['epoch']}), seed {run['seed']}; Pareto row "
                      f"k = {row['k']}",
            "J1": row["J1"], "J2": row["J2"]}
    REFERENCE.with_suffix(".meta.json").write_text(json.dumps(meta, indent=1) + "\n")
    print(f"wrote {REFERENCE} and its .meta.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
