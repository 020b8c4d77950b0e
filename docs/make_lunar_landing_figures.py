#!/usr/bin/env python
"""Make the S3 figures the docs show: docs/figures/lunar_landing.png and docs/figures/lunar_dispersion.png.

    python docs/make_lunar_landing_figures.py [--fmus DIR] [--out DIR]

The first is the paper's Figs. 1-2 (Mozzhorina 2017) from the shooting solution (the paper's
RK4 + interpolated switch scheme); the second flies the seeded dispersion (40 starts + the 8
corners, seed 2017) through the FMUs with the program and the feedback law.  The same figures:
``descent-fmus lunar-landing solve --method interpolate --plot FILE`` and
``descent-fmus lunar-landing fly --dispersion 40 --plot FILE``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from descent_fmus.synthesis.systems.lunar_landing.solution import plot_solution, solve_landing
from descent_fmus.synthesis.systems.lunar_landing.study import (LandingLoops, dispersion,
                                                                dispersion_table,
                                                                plot_dispersion)

DOCS = Path(__file__).resolve().parent / "figures"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=None,
                    help="folder of the built FMUs (default: fmus/ of the checkout, or "
                         "$DESCENT_FMUS_DIR)")
    ap.add_argument("--out", type=Path, default=DOCS, help="output folder (default docs/figures/)")
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    sol = solve_landing(method="interpolate")
    print(plot_solution(sol, args.out / "lunar_landing.png"))
    with LandingLoops(args.fmus) as loops:
        rows = dispersion(loops, n=40, seed=2017)
        print(dispersion_table(rows)[0])
        print(plot_dispersion(loops, rows, args.out / "lunar_dispersion.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
