#!/usr/bin/env python
"""Make the S3 figures the README shows: docs/lunar_landing.png and docs/lunar_dispersion.png.

    python docs/make_landing_figures.py [--fmus DIR]

The first is the paper's Figs. 1-2 (seed 002) from the shooting solution; the second flies the
seeded dispersion (40 starts + 8 corners) through the FMUs with the program and the feedback law.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from descent_fmus.synthesis.systems.lunar_landing.study import (LandingLoops, dispersion, dispersion_table,  # noqa: E402
                               plot_dispersion, plot_solution, solve_landing)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=ROOT / "fmus")
    ap.add_argument("--out", type=Path, default=ROOT / "docs")
    args = ap.parse_args(argv)
    sol = solve_landing(method="interpolate")
    print(plot_solution(sol, args.out / "lunar_landing.png"))
    with LandingLoops(args.fmus) as loops:
        rows = dispersion(loops, n=40, seed=2017)
        print(dispersion_table(rows)[0])
        print(plot_dispersion(loops, rows, args.out / "lunar_dispersion.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
