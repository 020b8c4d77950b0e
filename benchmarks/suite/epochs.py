#!/usr/bin/env python
"""The structure search's epochs in a suite run: one row per epoch of the network operator
(``VariationalGA.stats["epochs"]``, kept in the run's checkpoint) -- the flights so far, the best
law's target value, the population's diversity (distinct structures, the share of members with
the best law's structure, the mean number of matrix entries in which a member differs from the
best law's), the children flown and accepted since the epoch before, restarts and islands -- and
the learning curve's value at a few flight marks.  Reads runs, runs nothing.

    python benchmarks/suite/epochs.py runs/suite/parking/network-operator-s3
    python benchmarks/suite/epochs.py runs/suite/parking/network-operator-s* --marks 8000 20000
    python benchmarks/suite/epochs.py RUN --json
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def read(run: Path) -> dict:
    """``{"epochs": [...], "curve": [[flights, value], ...], "stats": {...}}`` of a run folder
    (its checkpoint; the summary's curve when it is finished)."""
    ck = run / "checkpoint.json"
    if not ck.is_file():
        raise ValueError(f"{run}: no checkpoint.json (not a synthesis run folder)")
    st = json.loads(ck.read_text())
    stats = (st.get("method") or {}).get("stats", {})
    curve = st.get("curve", [])
    summary = run / "summary.json"
    if summary.is_file():
        curve = json.loads(summary.read_text()).get("curve", curve)
    return {"epochs": stats.get("epochs", []), "curve": curve,
            "stats": {k: v for k, v in stats.items() if k != "epochs"}}


def value_at(curve, flights: int):
    """The learning curve's best value after at most ``flights`` flights (None before)."""
    out = None
    for n, v in curve:
        if n > flights:
            break
        out = v
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--marks", type=int, nargs="*", default=[8000, 20000, 32000])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = {}
    for run in args.runs:
        try:
            out[str(run)] = r = read(run)
        except (ValueError, OSError, json.JSONDecodeError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)
        r["marks"] = {m: value_at(r["curve"], m) for m in args.marks}
    if args.json:
        print(json.dumps(out, indent=1))
        return
    for run, r in out.items():
        last = r["curve"][-1] if r["curve"] else (0, None)
        print(f"\n{run}: {last[0]} flights, best {last[1]}; at "
              + ", ".join(f"{m}: {v:.4g}" if v is not None else f"{m}: -"
                          for m, v in r["marks"].items()))
        print(f"{'gen':>5} {'evals':>6} {'best':>10} {'forms':>5} {'share':>6} {'dist':>6} "
              f"{'child':>6} {'acc':>5} {'acc%':>5} {'rst':>3} {'isl':>3}")
        for e in r["epochs"]:
            rate = 100.0 * e["accepted"] / e["children"] if e["children"] else 0.0
            print(f"{e['gen']:5d} {e['evals']:6d} {e['best']:10.4g} {e['forms']:5d} "
                  f"{e['share_best']:6.2f} {e['dist']:6.1f} {e['children']:6d} "
                  f"{e['accepted']:5d} {rate:5.1f} {e['restarts']:3d} {e.get('islands', 0):3d}")


if __name__ == "__main__":
    main()
