"""Closed-loop FMUs on the package's engine (``synthesis/fmi/native/c/loop/closed_loop.c``): any
output interval with the controller at its own period (zero-order hold), the former flight bit
for bit at the law's step, and messages that reach a plain ``fmpy simulate``.

Oracles: fmpy's container FMU of the same wiring and component FMUs (the former closed-loop FMU,
built here with ``engine=False``: fixed step, the same Gauss-Seidel master) for the bitwise
checks; the flight at the law's step for the held control; the FMUs' own messages, which a
plain ``fmpy simulate`` printed only for the native plants before (issue #39).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from descent_fmus.synthesis.fmi.containers import closed_loop_fmu
from descent_fmus.synthesis.registry import closed_loop_specs

FMPY = [sys.executable, "-m", "fmpy"]           # the fmpy command line (fmpy/__main__.py)
KINDS = ("pythonfmu", "native")


def _folder(fmu_dir: Path, kind: str) -> Path:
    return fmu_dir if kind == "pythonfmu" else fmu_dir / "native"


def _loop(fmu_dir: Path, kind: str, name: str = "ReentryClosedLoop") -> Path:
    path = _folder(fmu_dir, kind) / f"{name}.fmu"
    if not path.is_file():
        pytest.skip(f"{path} is not built (python build_fmus.py; native: a C compiler)")
    if read_model_description(str(path)).coSimulation.modelIdentifier != "closed_loop":
        pytest.skip(f"{path} is fmpy's container (no C compiler at build time)")
    return path


def _old_container(spec, folder: Path, dest: Path) -> Path:
    """fmpy's container FMU of ``spec`` with the component FMUs of ``folder`` (as
    ``build_fmus.py`` picks them): the closed-loop FMU as it was before the engine."""
    w = spec.wiring
    ctrl = folder / (f"{w.name}Controller.fmu" if spec.controller_defaults is not None
                     else f"{w.controller}.fmu")
    return closed_loop_fmu(w, folder / f"{w.plant}.fmu", ctrl, dest,
                           parameters=spec.parameters, engine=False)


def _same_bits(a, b) -> bool:
    """Two structured result arrays hold the same columns and the same bits."""
    return a.dtype.names == b.dtype.names and all(
        a[n].tobytes() == b[n].tobytes() for n in a.dtype.names)


@pytest.mark.parametrize("kind", KINDS)
def test_an_output_interval_off_the_law_step_holds_the_control(fmu_dir, kind):
    # S1 at output interval 0.3 s (the law samples every 1 s, so sample instants fall inside
    # the host's steps): outputs at k * 0.3 s, the control constant between two whole seconds
    # (zero-order hold) and, at each sample, the control of the 1 s flight up to the plant's
    # integration error (sub-steps of at most 0.3 s instead of 1 s)
    path = _loop(fmu_dir, kind)
    res = simulate_fmu(str(path), output_interval=0.3, output=["u", "L", "status"])
    ref = simulate_fmu(str(path), output=["u", "L", "status"])
    t, u = res["time"], res["u"]
    assert np.abs(t - 0.3 * np.arange(len(t))).max() < 1e-9 and abs(t[-1] - 300.0) < 0.3
    second = np.floor(t + 1e-9).astype(int)
    same = second[1:] == second[:-1]
    assert (u[1:][same] == u[:-1][same]).all()
    assert (u[1:] != u[:-1]).sum() > 100                    # and it does act every second
    flying = ref["status"][second] == 0
    assert np.abs(u[flying] - ref["u"][second[flying]]).max() < 1e-6
    assert res[-1]["status"] == 1 and abs(res[-1]["L"] - ref[-1]["L"]) < 1.0


@pytest.mark.parametrize("kind", KINDS)
def test_at_the_law_step_the_flight_is_the_former_one_bit_for_bit(fmu_dir, kind, tmp_path):
    # every output at every point of fmpy simulate at the loop's step, engine vs fmpy's
    # container of the same components: the same bits
    path = _loop(fmu_dir, kind)
    spec = next(s for s in closed_loop_specs() if s.wiring.name == "ReentryClosedLoop")
    old = _old_container(spec, _folder(fmu_dir, kind), tmp_path / "Old.fmu")
    assert _same_bits(simulate_fmu(str(path), output_interval=1.0),
                      simulate_fmu(str(old), output_interval=1.0))


def _fmpy_simulate(path: Path, *args) -> str:
    """What a plain ``fmpy simulate`` (no --debug-logging) prints, stdout and stderr."""
    r = subprocess.run([*FMPY, "simulate", str(path), *args], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode != 0
    return r.stdout + r.stderr


@pytest.mark.parametrize("kind", KINDS)
def test_a_bad_start_value_of_a_plant_is_printed(fmu_dir, kind):
    # (a) the pythonfmu plant, (b) its native twin: the plant's own message
    path = _folder(fmu_dir, kind) / "Reentry.fmu"
    if not path.is_file():
        pytest.skip(f"{path} is not built")
    out = _fmpy_simulate(path, "--start-values", "m", "-5")
    assert "parameter m must be > 0, got -5" in out


@pytest.mark.parametrize("kind", KINDS)
def test_a_closed_loop_prints_its_components_and_its_own_errors(fmu_dir, kind):
    # (c) a bad start value of the plant inside a closed loop: the plant's message with the
    # component's name; a bad sample period and a bad communication step: the engine's own
    path = _loop(fmu_dir, kind)
    out = _fmpy_simulate(path, "--start-values", "m", "-5")
    assert "plant (Reentry): parameter m must be > 0, got -5" in out
    assert "ReentryClosedLoop: plant fmi2ExitInitializationMode failed" in out
    out = _fmpy_simulate(path, "--start-values", "sample_period", "-1")
    assert "ReentryClosedLoop: sample_period must be finite and >= 0" in out
    out = _fmpy_simulate(path, "--output-interval", "-1")
    assert "ReentryClosedLoop: the communication step must be finite and > 0, got -1 s" in out


def test_debug_messages_stay_off_unless_asked(fmu_dir, tmp_path):
    # a flight that goes well prints nothing without --debug-logging (only the filter passes
    # errors and warnings: the pythonfmu plant is instantiated with its logging on)
    path = _loop(fmu_dir, "pythonfmu")
    r = subprocess.run([*FMPY, "simulate", str(path), "--output-file",
                        str(tmp_path / "out.csv")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "" and r.stderr.strip() == ""


INTERVALS = (0.1, 0.25, 1.0)


@pytest.mark.slow        # every closed loop, pythonfmu and native, at four intervals (~50 s)
@pytest.mark.parametrize("kind", KINDS)
def test_every_closed_loop_at_every_interval(fmu_dir, kind, tmp_path):
    # every registered closed loop: fmpy simulate at 0.1, 0.25 and 1 s and at the law's step
    # runs to the stop time with outputs at the asked times; at the law's step every output is
    # that of fmpy's container of the same components, bit for bit
    folder = _folder(fmu_dir, kind)
    specs = [s for s in closed_loop_specs() if (folder / f"{s.wiring.name}.fmu").is_file()]
    if kind == "native" and not specs:
        pytest.skip("no native closed loop built")
    assert kind == "native" or len(specs) == len(closed_loop_specs())
    for spec in specs:
        w = spec.wiring
        path = _loop(fmu_dir, kind, w.name)
        stop = min(w.stop_time, 20.0)
        for interval in sorted({*INTERVALS, w.step}):
            res = simulate_fmu(str(path), output_interval=interval, stop_time=stop)
            t = res["time"]
            assert abs(t[1] - interval) < 1e-12 and abs(t[-1] - stop) <= interval, w.name
        old = _old_container(spec, folder, tmp_path / f"{w.name}.fmu")
        assert _same_bits(simulate_fmu(str(path), output_interval=w.step, stop_time=stop),
                          simulate_fmu(str(old), output_interval=w.step, stop_time=stop)), w.name


@pytest.mark.parametrize("kind", KINDS)
def test_the_one_pass_archive_is_fmpys_container_on_the_engine(fmu_dir, kind, tmp_path):
    # Oracle: fmpy's container archive of the same wiring (engine=False) made an engine
    # closed loop by into_engine -- the former route, which compressed the archive three
    # times.  The closed loop written in one pass (components' members copied compressed) holds
    # the same files with the same bytes; only the instantiation token (a fresh uuid per
    # container) differs.
    import re
    import zipfile

    from descent_fmus.synthesis.fmi.containers import into_engine
    _loop(fmu_dir, kind)                     # skips where the engine cannot be built
    spec = next(s for s in closed_loop_specs() if s.wiring.name == "ReentryClosedLoop")
    folder = _folder(fmu_dir, kind)
    old = into_engine(_old_container(spec, folder, tmp_path / "old" / "ReentryClosedLoop.fmu"))
    w = spec.wiring
    new = closed_loop_fmu(w, folder / f"{w.plant}.fmu", folder / f"{w.controller}.fmu",
                          tmp_path / "new" / "ReentryClosedLoop.fmu", parameters=spec.parameters)

    def files(path):
        with zipfile.ZipFile(path) as z:
            assert z.testzip() is None                      # every member's CRC holds
            token = re.search(rb'guid="([^"]+)"', z.read("modelDescription.xml")).group(1)
            return {i.filename: z.read(i.filename).replace(token, b"TOKEN")
                    for i in z.infolist() if not i.is_dir()}
    a, b = files(old), files(new)
    assert sorted(a) == sorted(b) and all(a[n] == b[n] for n in a)
    # no member is left stored that the former archive deflated: about as small
    assert new.stat().st_size <= 1.05 * old.stat().st_size
