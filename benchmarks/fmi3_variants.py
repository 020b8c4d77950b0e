"""Benchmark: what the FMI 3.0 variants of the native FMUs add to a build.

For every native FMI 2.0 FMU of ``fmus/native/`` (not the closed loops), in one process:

* **alone** -- :func:`fmi3_variant` with nothing compiled before: the model's C and the wrapper;
* **reused** -- the same inside ``reusing_objects()`` once the model's objects exist, as in
  ``build_fmus.py``, where the FMI 2.0 build of the same model has just compiled them: the
  wrapper (once) and the link;
* **validate** -- ``fmpy.validation.validate_fmu`` of the FMI 2.0 FMU and of its variant (what
  ``build_fmus.py --validate`` adds).

Prints the seconds per FMU and the totals, the ratio alone / reused, with the machine's load
average.  Timings are measured, never asserted.

    python benchmarks/fmi3_variants.py [--fmus DIR] [--no-validate] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from descent_fmus.synthesis.fmi.native.builders.build import reusing_objects
from descent_fmus.synthesis.fmi.native.builders.fmi3 import fmi3_variant, is_native

ROOT = Path(__file__).resolve().parent.parent


def _timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


def measure(native_dir: Path, validate: bool) -> list:
    """One row per native FMU: name, seconds alone, reused, validate FMI 2.0, validate FMI 3.0."""
    from fmpy.validation import validate_fmu
    fmus = [p for p in sorted(native_dir.glob("*.fmu")) if is_native(p)]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for fmu in fmus:
            alone = _timed(fmi3_variant, fmu, tmp / "alone" / fmu.name)
            rows.append({"fmu": fmu.stem, "alone": alone})
        with reusing_objects():
            for fmu in fmus:              # the model's objects, as the FMI 2.0 build leaves them
                fmi3_variant(fmu, tmp / "warm" / fmu.name)
            for row, fmu in zip(rows, fmus):
                row["reused"] = _timed(fmi3_variant, fmu, tmp / "reused" / fmu.name)
        if validate:
            for row, fmu in zip(rows, fmus):
                row["validate_fmi2"] = _timed(validate_fmu, str(fmu))
                row["validate_fmi3"] = _timed(validate_fmu, str(tmp / "reused" / fmu.name))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=ROOT / "fmus", help="the built FMUs (fmus/)")
    ap.add_argument("--no-validate", action="store_true", help="leave fmpy's validation out")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    load = os.getloadavg()[0]
    rows = measure(args.fmus / "native", not args.no_validate)
    keys = [k for k in ("alone", "reused", "validate_fmi2", "validate_fmi3") if k in rows[0]]
    total = {k: sum(r[k] for r in rows) for k in keys}
    if args.json:
        print(json.dumps({"load": load, "rows": rows, "total": total}, indent=1))
        return 0
    print(f"{len(rows)} native FMUs, load average {load:.1f} at the start")
    print("| FMU | " + " | ".join(f"{k} [s]" for k in keys) + " |")
    print("| --- |" + " --- |" * len(keys))
    for r in rows:
        print(f"| {r['fmu']} | " + " | ".join(f"{r[k]:.2f}" for k in keys) + " |")
    print("| **total** | " + " | ".join(f"**{total[k]:.1f}**" for k in keys) + " |")
    print(f"alone / reused: {total['alone'] / total['reused']:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
