"""FMI 3.0 variants of the native closed loops (``fmus/native/fmi3/<Name>ClosedLoop.fmu``): the
closed-loop engine under the FMI 3.0 wrapper, its FMI 2.0 components in ``resources/``.

Oracles: the FMI 2.0 closed loop the variant is made from (the same engine and components, so
fmpy's simulation of the two gives the same outputs, bitwise, at every output point; the FMI 2.0
loop is itself checked against fmpy's container in ``tests/fmi/test_closed_loop_engine.py``);
fmpy's validation; the FMI 2.0 model description (the same variables); the messages of the
engine and of the components, which the FMI 3.0 face relays.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

from descent_fmus.synthesis.cli.main import main
from descent_fmus.synthesis.fmi.containers import closed_loop_fmu
from descent_fmus.synthesis.fmi.native.builders.build import (find_compiler, platform_folder,
                                                              platform_tuple)
from descent_fmus.synthesis.fmi.loop_fmi3 import (any_fmi3_variant, build_loop_variants,
                                                  is_closed_loop, loop_variant)
from descent_fmus.synthesis.fmi.native.builders.fmi3 import NotNativeError, fmi3_variant
from descent_fmus.synthesis.registry import closed_loop_specs
from test_native_fmi3 import (_csv_of_fmi2_and_fmi3, _Host, _refused_start_value,
                              _simulate, fmi3_pairs)

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")


@pytest.fixture(scope="module")
def loops(fmu_dir, tmp_path_factory) -> dict:
    """name -> (FMI 2.0 native closed loop, its FMI 3.0 variant): the variants build_fmus.py
    wrote, or (an older build without them) made here."""
    return fmi3_pairs(fmu_dir, tmp_path_factory, "*ClosedLoop.fmu", is_closed_loop,
                      build_loop_variants)


def test_every_native_loop_has_a_valid_fmi3_variant(loops):
    # the 7 native closed loops of the registry, each valid for fmpy, with the FMI 2.0 loop's
    # variables (names, value references, starts, units), time at its value reference 0, its
    # resources (the FMI 2.0 components, loop.txt) byte for byte and the FMI 3.0 binary only
    specs = {s.wiring.name for s in closed_loop_specs()}
    assert len(loops) >= 7 and set(loops) <= specs
    for name, (fmu2, fmu3) in loops.items():
        assert validate_fmu(str(fmu3)) == [], name
        md2, md3 = read_model_description(str(fmu2)), read_model_description(str(fmu3))
        assert md3.fmiVersion == "3.0" and md3.instantiationToken == md2.guid, name
        assert md3.modelName == md2.modelName == name
        assert md3.coSimulation.modelIdentifier == "closed_loop"
        same = {v.name: (v.valueReference, v.causality, v.start, v.unit)
                for v in md2.modelVariables if v.name != "time"}
        assert {v.name: (v.valueReference, v.causality, v.start, v.unit)
                for v in md3.modelVariables if v.name != "time"} == same, name
        (time,) = [v for v in md3.modelVariables if v.causality == "independent"]
        assert time.name == "time" and time.valueReference == 0
        with zipfile.ZipFile(fmu2) as z2, zipfile.ZipFile(fmu3) as z3:
            res2 = {n: z2.read(n) for n in z2.namelist() if n.startswith("resources/")}
            res3 = {n: z3.read(n) for n in z3.namelist() if n.startswith("resources/")}
            binaries = [n for n in z3.namelist() if n.startswith("binaries/")]
        assert res3 == res2 and "resources/loop.txt" in res3, name
        assert binaries == [f"binaries/{platform_tuple()}/closed_loop{platform_folder()[1]}"]


def test_loop_variants_fly_as_fmi2_bitwise(loops):
    # fmpy simulates each loop at the law's step and at 0.25 s (sample instants inside the
    # host's steps for a 1 s law): every output at every point equal to the FMI 2.0 loop's
    steps = {s.wiring.name: s.wiring.step for s in closed_loop_specs()}
    for name, (fmu2, fmu3) in loops.items():
        stop = read_model_description(str(fmu2)).defaultExperiment.stopTime
        for interval in (steps[name], 0.25):
            a = _simulate(fmu2, output_interval=interval)
            b = _simulate(fmu3, output_interval=interval)
            assert isinstance(a, dict), f"{name} at {interval} s: {a}"
            assert a == b, f"{name} at {interval} s"
            points = len(a["time"]) // 8                     # float64 bytes
            assert points == round(float(stop) / interval) + 1, name


def test_fmpy_simulate_cli_on_a_loop_variant(loops, tmp_path):
    # the fmpy command line: an output interval off the law's step gives the FMI 2.0 loop's CSV
    # to the byte; a component's bad start value is printed without --debug-logging
    fmu2, fmu3 = loops["ReentryClosedLoop"]
    two, three = _csv_of_fmi2_and_fmi3(fmu2, fmu3, tmp_path, "--output-interval", "0.1")
    assert three == two
    assert "[ERROR] plant (Reentry): parameter m must be > 0, got -5.0" in \
        _refused_start_value(fmu3, "m", "-5")
    assert ("[ERROR] ReentryClosedLoop: sample_period must be finite and >= 0 (0: at the "
            "loop's step), got -1 s") in _refused_start_value(fmu3, "sample_period", "-1")


def test_loop_variant_calls_and_messages(loops, tmp_path):
    # the FMI 3.0 face's own calls on the engine: time (value reference 0, read-only), the
    # features a closed loop has not, each an error in the engine's words; a resource path
    # with a space and a '%' (the engine gets it as a file URI, decoded back)
    fmu3 = loops["ReentryClosedLoop"][1]
    host = _Host(fmu3, tmp_path / "a b%41")
    assert host.instantiate(), host.messages
    s, t = host.slave, host.vr["time"]
    assert t == 0
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.doStep(0.0, 0.25)
    assert s.getFloat64([t]) == [0.25]
    del host.messages[:]
    assert host.status("setFloat64", [t], [1.0]) == 3
    assert host.status("getFMUState") == 3
    assert host.status("setBoolean", [0], [True]) == 3
    assert host.status("getString", []) == 0              # asked for nothing: fine
    assert [m for _, m in host.messages] == [
        "ReentryClosedLoop: value reference 0 is the independent variable time and cannot "
        "be set",
        "ReentryClosedLoop: fmi3GetFMUState is not supported by this closed-loop FMU",
        "ReentryClosedLoop: this closed-loop FMU has no Boolean variables"]
    s.terminate()
    s.freeInstance()


def test_model_exchange_is_refused_with_the_wrapped_message(loops, fmu_dir, tmp_path):
    # fmi3InstantiateModelExchange of a closed loop and of a native plant: the FMI 2.0
    # implementation's own refusal (fmi2Instantiate as model exchange), through the logger
    for fmu in (loops["ReentryClosedLoop"][1], fmu_dir / "native" / "fmi3" / "Reentry.fmu"):
        if not fmu.is_file():
            continue
        md = read_model_description(str(fmu))
        unzipped = tmp_path / fmu.stem
        with zipfile.ZipFile(fmu) as z:
            z.extractall(unzipped)
        messages = []
        model = FMU3Model(guid=md.instantiationToken, unzipDirectory=str(unzipped),
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName="me")
        with pytest.raises(Exception, match="Failed to instantiate FMU"):
            model.instantiate(logMessage=lambda env, status, cat, msg: messages.append(
                (status, msg.decode())))
        assert len(messages) == 1 and messages[0][0] == 3, fmu
        assert messages[0][1].endswith(": this FMU supports co-simulation only"), messages


def test_loop_variant_exports_the_fmi3_functions_only(loops, tmp_path):
    # the 75 functions of the FMI 3.0 headers, none of the engine's FMI 2.0 ones inside it
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) not installed")
    with zipfile.ZipFile(loops["ReentryClosedLoop"][1]) as z:
        (so,) = [n for n in z.namelist() if n.startswith("binaries/")]
        (tmp_path / "lib.so").write_bytes(z.read(so))
    dyn = subprocess.run([nm, "-D", "--defined-only", str(tmp_path / "lib.so")],
                         capture_output=True, text=True, check=True).stdout
    exported = {line.split()[-1] for line in dyn.splitlines() if " T " in line}
    assert len(exported) == 75 and all(n.startswith("fmi3") for n in exported)


def test_fmi3_variant_command_on_a_closed_loop(loops, fmu_dir, tmp_path, capsys):
    # descent-fmus fmi3-variant on a closed loop of the engine writes the variant that flies as
    # the FMI 2.0 loop; on fmpy's container (no engine) it is one line, exit 2, nothing written
    fmu2 = loops["TelescopeClosedLoop"][0]
    out = tmp_path / "Loop3.fmu"
    assert main(["fmi3-variant", str(fmu2), "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["out"] == str(out)
    assert _simulate(out, output_interval=0.25) == _simulate(fmu2, output_interval=0.25)
    # a pythonfmu closed loop runs on the same engine: its variant too
    py2 = fmu_dir / "ReentryClosedLoop.fmu"
    if is_closed_loop(py2):
        assert main(["fmi3-variant", str(py2), "--out", str(tmp_path / "Py3.fmu")]) == 0
        capsys.readouterr()
        a, b = _simulate(py2, output_interval=1.0), _simulate(tmp_path / "Py3.fmu",
                                                              output_interval=1.0)
        assert isinstance(a, dict) and a == b
    spec = next(s for s in closed_loop_specs() if s.wiring.name == "TelescopeClosedLoop")
    native, w = fmu_dir / "native", spec.wiring
    ctrl = native / (f"{w.name}Controller.fmu" if spec.controller_defaults is not None
                     else f"{w.controller}.fmu")
    container = closed_loop_fmu(w, native / f"{w.plant}.fmu", ctrl, tmp_path / "Old.fmu",
                                parameters=spec.parameters, engine=False)
    with pytest.raises(NotNativeError, match="nor a closed loop of its engine"):
        any_fmi3_variant(container, tmp_path / "again.fmu")
    with pytest.raises(NotNativeError, match="is not a closed loop of the descent-fmus engine"):
        loop_variant(container, tmp_path / "again.fmu")
    with pytest.raises(NotNativeError, match="is not a native FMI 2.0 FMU of descent-fmus"):
        fmi3_variant(fmu2, tmp_path / "again.fmu")        # the native FMUs' function
    assert main(["fmi3-variant", str(container), "--out", str(tmp_path / "c.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nor a closed loop of its engine" in err
    assert not (tmp_path / "c.fmu").exists() and not (tmp_path / "again.fmu").exists()
