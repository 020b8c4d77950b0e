#!/usr/bin/env python
"""Build every FMU of descent-fmus into fmus/ (plants, controllers, closed loops + SSP files).

Usage: ``python build_fmus.py [--validate] [--out DIR]``.  Run it from anywhere; the output
goes to ``fmus/`` beside this file.  Every FMU is FMI 2.0 co-simulation (pythonfmu); the
``*ClosedLoop.fmu`` are fmpy container FMUs that ``fmpy simulate`` runs directly.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))

from synthesis import scenarios  # noqa: E402
from synthesis.export import build_slave, closed_loop_fmu, with_defaults, write_ssp  # noqa: E402

FMU_DIR = ROOT / "fmus"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--validate", action="store_true", help="run fmpy's validation on each FMU")
    ap.add_argument("--out", type=Path, default=FMU_DIR, help="output folder (default fmus/)")
    args = ap.parse_args(argv)
    scenarios.load_all()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    built = []
    for script in scenarios.SLAVES:
        t0 = time.perf_counter()
        path = build_slave(ROOT / script, out)
        built.append(path)
        print(f"built {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path} "
              f"({time.perf_counter() - t0:.1f} s)")
    for name, spec in scenarios.CLOSED_LOOPS.items():
        w = spec.wiring
        plant = out / f"{w.plant}.fmu"
        ctrl = out / f"{spec.controller_fmu or w.controller}.fmu"
        if spec.controller_defaults:
            ctrl = with_defaults(out / f"{w.controller}.fmu", out / f"{name}Controller.fmu",
                                 spec.controller_defaults)
        fmu = closed_loop_fmu(w, plant, ctrl, out / f"{name}.fmu", parameters=spec.parameters)
        ssp = write_ssp(w, plant, ctrl, out / f"{name}.ssp")
        built.append(fmu)
        print(f"built {fmu.name} and {ssp.name}")
    if args.validate:
        from fmpy.validation import validate_fmu
        bad = 0
        for path in built:
            problems = validate_fmu(str(path))
            if problems:
                bad += 1
                print(f"{path.name}: {len(problems)} problem(s):\n  " + "\n  ".join(problems))
        if bad:
            return 1
        print(f"fmpy validate: no problems in {len(built)} FMUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
