#!/usr/bin/env python
"""Make the S4 figures of the docs: the reorientations and the route by the direct method.

* ``docs/figures/telescope_rigid.png`` -- u(t), omega(t), lambda(t), beta(t), the CMG singularity measure
  and the miss per iteration of the rigid reorientation (Voronov 2009, Example 1);
* ``docs/figures/telescope_flexible.png`` -- the same with the modal coordinates for the flexible
  telescope and the reduced algorithm (Example 2);
* ``docs/figures/telescope_route.png`` -- the route of Example 3 traced by halving: gimbal rates with the
  stage joints, deviation from the route against eps, the route.

    python docs/make_telescope_figures.py [--out DIR]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from descent_fmus.synthesis.systems.telescope.reorientation import plot_reorientation, reorient
from descent_fmus.synthesis.systems.telescope.route import plot_route, trace

DOCS = Path(__file__).resolve().parent / "figures"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DOCS, help="output folder (default docs/figures/)")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    args.out.mkdir(parents=True, exist_ok=True)
    for model in ("rigid", "flexible"):
        path = plot_reorientation(reorient(flexible=model == "flexible"),
                                  args.out / f"telescope_{model}.png")
        print(f"wrote {path}")
    print(f"wrote {plot_route(trace(), args.out / 'telescope_route.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
