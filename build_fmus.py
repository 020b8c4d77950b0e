#!/usr/bin/env python
"""Build every FMU of descent-fmus into fmus/ (plants, controllers, closed loops + SSP files).

Usage: ``python build_fmus.py [--validate] [--out DIR] [--system STEM ...]``, after
``pip install -e .``.  The output goes to ``fmus/`` beside this file unless ``--out`` says
otherwise.  What is built comes from the registry of systems (``synthesis/registry.py``): every
system's pythonfmu FMU classes, then its closed loops as fmpy container FMUs (``fmpy simulate``
runs them directly) with an SSP file beside each, then the native (C) plants and controller
twins the systems name into ``native/`` and the closed loops whose plant and controller both have
twins there (skipped, with one line, where no C compiler exists), and the FMI 3.0 variants of the
native plants, controllers and closed loops into ``native/fmi3/``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

FMU_DIR = Path(__file__).resolve().parent / "fmus"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--validate", action="store_true", help="run fmpy's validation on each FMU")
    ap.add_argument("--out", type=Path, default=FMU_DIR, help="output folder (default fmus/)")
    ap.add_argument("--system", nargs="+", metavar="STEM",
                    help="build only these systems (default: all)")
    args = ap.parse_args(argv)
    try:
        from descent_fmus.synthesis.fmi.compose import build_slave, with_defaults
        from descent_fmus.synthesis.fmi.native.builders.build import reusing_objects
        from descent_fmus.synthesis.fmi.native.builders.closed_loops import build_native_fmus
        from descent_fmus.synthesis.fmi.loop_fmi3 import build_loop_variants
        from descent_fmus.synthesis.fmi.native.builders.fmi3 import build_fmi3_variants
        from descent_fmus.synthesis.fmi.native.builders.plant_fmu import build_native_plants
        from descent_fmus.synthesis.registry import (SYSTEMS, get_system, native_controllers,
                                                     native_plants)
    except ImportError as exc:
        print(f"build_fmus.py: cannot import descent_fmus ({exc}); install the project first: "
              f"pip install -e .", file=sys.stderr)
        return 2
    try:
        systems = [get_system(s) for s in (args.system or SYSTEMS)]
    except KeyError as exc:
        print(f"build_fmus.py: {exc.args[0]}", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    built, done = [], set()
    for system in systems:
        for fmu_class in system.fmus:
            if fmu_class in done:
                continue
            done.add(fmu_class)
            t0 = time.perf_counter()
            path = build_slave(fmu_class, out)
            built.append(path)
            print(f"built {path.name} ({time.perf_counter() - t0:.1f} s)")
    for system in systems:
        for spec in system.closed_loops:
            w = spec.wiring
            plant, ctrl = out / f"{w.plant}.fmu", out / f"{w.controller}.fmu"
            if spec.controller_defaults is not None:
                ctrl = with_defaults(ctrl, out / f"{w.name}Controller.fmu",
                                     spec.controller_defaults())
                built.append(ctrl)
            fmu, ssp = spec.write(plant, ctrl, out)
            built.append(fmu)
            print(f"built {fmu.name} and {ssp.name}")
    # the native plants (C generated from models/) and controller twins the systems name, and
    # the closed loops whose twins are all built; then the FMI 3.0 variants of the native plants
    # and controllers, which reuse their FMI 2.0 twins' compiled model (reusing_objects), and of
    # the native closed loops (the engine's FMI 3.0 binary, their FMI 2.0 components)
    with reusing_objects():
        native = build_native_plants(out / "native", native_plants(systems))
        native += build_native_fmus(out / "native", native_controllers(systems),
                                    [s for sy in systems for s in sy.closed_loops])
        built += native + build_fmi3_variants(native, out / "native" / "fmi3")
        built += build_loop_variants(native, out / "native" / "fmi3")
    warm_caches(out, systems)
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


def warm_caches(out: Path, systems) -> None:
    """[choice] Fill, once, what the main job would otherwise build on a fresh machine's first
    run (docs/methods/run_loop.md, "A fresh machine's first run"): the C master, the
    equivalence probes' library and the native interpreter law FMU (each compiled into the
    cache folder under a key of its sources, compiler and flags: the main job finds them there,
    and builds them itself when they are absent), matplotlib's font list and the package's
    bytecode.  Skipped, with one line, where something is missing (no C compiler, a read-only
    cache): nothing here is needed for the FMUs."""
    t0 = time.perf_counter()
    done = []
    try:
        from descent_fmus.synthesis.fmi.c_master_loop import master_library
        from descent_fmus.synthesis.fmi.native.builders.law_fmu import interpreter_fmu
        from descent_fmus.synthesis.run.probes import native_prober
        master_library()
        interpreter_fmu()
        probed = set()
        for system in systems:
            for problem in (system.problems() if system.problems else ()):
                if problem.wiring.name not in probed:
                    probed.add(problem.wiring.name)
                    native_prober(problem, problem.fmu_paths(out))
        done.append("the C master, the probe library and the interpreter law FMU")
    except Exception as exc:        # no compiler, a build error: the main job tries again
        print(f"build_fmus.py: the native caches are left to the first run ({exc})")
    try:
        # matplotlib writes its font list on its first import in a process: a process of its
        # own, so that it is written even where this one has imported matplotlib already
        import subprocess
        subprocess.run([sys.executable, "-c", "import matplotlib.font_manager"], check=True,
                       capture_output=True, timeout=300)
        done.append("matplotlib's font list")
    except Exception as exc:
        print(f"build_fmus.py: matplotlib's font list is left to the first run ({exc})")
    if not sys.dont_write_bytecode:
        import compileall
        from descent_fmus import models, synthesis
        ok = all(compileall.compile_dir(d, quiet=1) for m in (models, synthesis)
                 for d in m.__path__)
        done.append("the package's bytecode" + ("" if ok else " (some files failed)"))
    print(f"warmed the caches: {', '.join(done) or 'nothing'} "
          f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    sys.exit(main())
