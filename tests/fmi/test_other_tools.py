"""Other FMI tools run our SSP files: the native co-simulation host ecos (ecospy) and the Open
Simulation Platform's libcosim (libcosimpy).

Oracle: our fmpy master (synthesis.fmi.closed_loop) on the same FMUs.  ecos and libcosim are
Jacobi masters (every component steps from the values the others had at the start of the step,
so the controller acts on y(t_k-1)); our master run with scheme="jacobi" does the same, and the
landing numbers must then agree: to the 6 decimals ecos prints; to 1e-9 at every communication
point for libcosim, which runs in this process and whose values are read as doubles.  The
default Gauss-Seidel scheme (fmpy's container FMU) differs by a one-step delay.
"""
from __future__ import annotations

import numpy as np
import pytest

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.other_tools import (EcosUnavailable, LibcosimUnavailable,
                                                    run_ecos, run_libcosim)
from descent_fmus.synthesis.registry import closed_loop_specs
from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.systems.reentry.flight import load_loop
from descent_fmus.synthesis.systems.reentry import wiring as spec
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law


def test_ecos_agrees_with_fmpy(fmu_dir, tmp_path):
    try:
        last = run_ecos(fmu_dir / "ReentryClosedLoop.ssp", spec.STEP, spec.WIRING.stop_time,
                        log={"plant": ["L", "load_max", "t_end", "status"]},
                        workdir=tmp_path)
    except EcosUnavailable as exc:  # e.g. a machine without libtbb12 (CI installs it)
        pytest.skip(str(exc))
    loop = load_loop(fmu_dir)
    try:
        ours = loop.run(spec.plant_values(ReentryParams()),
                        paper_basic_law().start_values(), scheme="jacobi").final
    finally:
        loop.close()
    assert last["plant::status"] == 1
    assert last["plant::t_end"] == pytest.approx(ours["t_end"], abs=2e-6)
    assert last["plant::L"] == pytest.approx(ours["L"], abs=2e-6)
    assert last["plant::load_max"] == pytest.approx(ours["load_max"], abs=2e-6)


def _libcosim_against_jacobi(spec, fmu_dir) -> tuple:
    """libcosim's flight of the native closed loop ``spec`` from its SSP file, and the package's
    master on the same two FMUs in the Jacobi scheme: (largest difference of a Real plant output
    at a communication point up to the stop, libcosim's run, the reference run)."""
    w, native = spec.wiring, fmu_dir / "native"
    ctrl = native / (f"{w.name}Controller.fmu" if spec.controller_defaults is not None
                     else f"{w.controller}.fmu")
    loop = ClosedLoop(w, native / f"{w.plant}.fmu", ctrl)
    names = [v.name for v in loop.plant.md.modelVariables
             if v.causality == "output" and v.type == "Real"]
    loop.record = [n for n in names if n not in dict(w.to_controller)]
    try:
        ref = loop.run(scheme="jacobi", record=True)
    finally:
        loop.close()
    try:
        host = run_libcosim(native / f"{w.name}.ssp", w.step, w.stop_time,
                            {"plant": names + ["status"]})
    except LibcosimUnavailable as exc:       # a machine without libcosimpy (the test extra)
        pytest.skip(str(exc))
    k = len(ref.time) - 1                    # libcosim's points are t_1, t_2, ...
    assert np.array_equal(host.time[:k], ref.time[1:])
    worst = max(float(np.max(np.abs(host.series[f"plant::{n}"][:k] - ref.outputs[n][1:])))
                for n in names)
    return worst, host, ref


def test_libcosim_flies_the_native_s1_loop_as_the_jacobi_master(fmu_dir):
    (s1,) = [s for s in closed_loop_specs() if s.wiring.name == "ReentryClosedLoop"]
    worst, host, ref = _libcosim_against_jacobi(s1, fmu_dir)
    assert worst <= 1e-9                     # measured: 0 (the same doubles)
    assert ref.stopped and host.final["plant::status"] == 1 == ref.final["status"]
    # after the landing libcosim steps the frozen plant on to 300 s: the landing stays
    for n in ("L", "load_max", "t_end"):
        assert host.final[f"plant::{n}"] == ref.final[n]
    # the scheme matters: the Gauss-Seidel flight lands 353 m further
    loop = ClosedLoop(s1.wiring, fmu_dir / "native" / "Reentry.fmu",
                      fmu_dir / "native" / "NetworkOperatorController.fmu")
    try:
        gs = loop.run().final
    finally:
        loop.close()
    assert abs(gs["L"] - host.final["plant::L"]) > 100.0


def test_libcosim_flies_every_native_loop_as_the_jacobi_master(fmu_dir):
    specs = [s for s in closed_loop_specs()
             if (fmu_dir / "native" / f"{s.wiring.name}.ssp").is_file()]
    assert len(specs) >= 7
    for spec in specs:
        worst, host, ref = _libcosim_against_jacobi(spec, fmu_dir)
        assert worst <= 1e-9, spec.wiring.name        # measured: 0 for all seven


def test_libcosim_bad_input_is_one_clear_error(fmu_dir):
    ssp = fmu_dir / "native" / "ReentryClosedLoop.ssp"
    cases = [({"pilot": ["L"]}, 1.0, ValueError, "has no component 'pilot'"),
             ({"plant": ["Lx"]}, 1.0, ValueError, "component 'plant' has no variable 'Lx'"),
             ({"plant": ["L"]}, 1e-10, ValueError, "libcosim steps whole nanoseconds")]
    for log, step, error, words in cases:
        try:
            with pytest.raises(error, match=words):
                run_libcosim(ssp, step, 300.0, log)
        except LibcosimUnavailable as exc:
            pytest.skip(str(exc))
    with pytest.raises(RuntimeError, match="libcosim cannot load"):
        run_libcosim(fmu_dir / "Reentry.fmu", 1.0, 300.0, {})       # not an SSP file
