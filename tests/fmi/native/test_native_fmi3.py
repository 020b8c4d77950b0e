"""FMI 3.0 variants of the native FMUs (``fmus/native/fmi3/``, ``export-law --fmi3``).

Oracles: the FMI 2.0 native FMU the variant is made from -- the same C model, so fmpy's
simulation of the two with the same start values and inputs gives the same outputs, bitwise, at
every output point; fmpy's validation (the FMI 3.0 schema and its checks); the variable table
the FMI 2.0 FMU was built from (the variant reads it back from the FMI 2.0 description); the
messages of the FMI 2.0 wrapper, which the FMI 3.0 one reuses.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from descent_fmus.synthesis.cli.main import main
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.description.fmi3 import model_description
from descent_fmus.synthesis.fmi.native.builders.build import (FMI3_GENERATION_TOOL, c_file,
                                                              find_compiler, fmi3_rows,
                                                              platform_folder, platform_tuple)
from descent_fmus.synthesis.fmi.native.builders.fmi3 import (NotNativeError, build_fmi3_variants,
                                                              fmi3_variant, is_native,
                                                              variables_of)
from descent_fmus.synthesis.fmi.native.builders.law_fmu import build_law_fmu, law_variables
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.registry import closed_loop_specs

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")

REENTRY_LAW = Path(__file__).resolve().parents[2] / "reference" / "reentry_five_term_law.json"


@pytest.fixture(scope="module")
def pairs(fmu_dir, tmp_path_factory) -> dict:
    """name -> (FMI 2.0 native FMU, its FMI 3.0 variant), for every native FMU but the closed
    loops (test_loop_fmi3.py): the variants build_fmus.py wrote, or (an older build without
    them) made here."""
    return fmi3_pairs(fmu_dir, tmp_path_factory, "*.fmu", is_native, build_fmi3_variants)


def fmi3_pairs(fmu_dir, tmp_path_factory, pattern: str, accept, build) -> dict:
    """name -> (FMI 2.0 native FMU, its FMI 3.0 variant) for the native FMUs matching
    ``pattern`` that ``accept`` takes: the variants in ``native/fmi3/``, or, if any is missing,
    all made by ``build`` in a temporary folder."""
    native = fmu_dir / "native"
    fmi2 = [p for p in sorted(native.glob(pattern)) if accept(p)]
    fmi3 = native / "fmi3"
    if not all((fmi3 / p.name).is_file() for p in fmi2):
        fmi3 = tmp_path_factory.mktemp("fmi3")
        build(fmi2, fmi3, say=lambda line: None)
    return {p.stem: (p, fmi3 / p.name) for p in fmi2}


def test_every_native_fmu_has_a_valid_fmi3_variant(pairs):
    # the plants, the controllers and the loops' own controllers (18 today); the closed loops'
    # variants: test_loop_fmi3.py
    assert {"Reentry", "NetworkOperatorController", "GuidedNetworkOperatorController",
            "ProgramController", "ReentryNPC", "Telescope"} <= set(pairs)
    for name, (fmu2, fmu3) in pairs.items():
        # fmpy's validation but its check of the variable names (seconds for a large FMU; the
        # names are the FMI 2.0 FMU's, checked equal below): all of it on the small ones, the
        # slow test below on the large ones
        md3 = read_model_description(str(fmu3), validate=True, validate_model_structure=True)
        if len(md3.modelVariables) < 100:
            assert validate_fmu(str(fmu3)) == [], name
        md2 = read_model_description(str(fmu2))
        assert md3.fmiVersion == "3.0" and md3.instantiationToken == md2.guid, name
        # the same variables (names, value references, causalities, starts, units) plus time
        same = {v.name: (v.valueReference, v.causality, v.start, v.unit, v.description)
                for v in md2.modelVariables}
        assert {v.name: (v.valueReference, v.causality, v.start, v.unit, v.description)
                for v in md3.modelVariables if v.name != "time"} == same, name
        (time,) = [v for v in md3.modelVariables if v.causality == "independent"]
        assert time.name == "time" and time.valueReference == len(same)
        assert {v.type for v in md3.modelVariables} <= {"Float64", "Int32"}
        with zipfile.ZipFile(fmu3) as z:
            assert "sources/buildDescription.xml" in z.namelist()


@pytest.mark.slow
def test_the_large_variants_pass_fmpy_validate(pairs):
    # the rest of fmpy's validation, its check of the variable names, on the variants the test
    # above leaves to it (some 12 s each for the largest)
    for name, (_, fmu3) in pairs.items():
        if len(read_model_description(str(fmu3)).modelVariables) >= 100:
            assert validate_fmu(str(fmu3)) == [], name


def test_a_variant_exports_the_fmi3_functions_only(pairs, tmp_path):
    # every FMI 3.0 function of the standard's headers, none of the FMI 2.0 wrapper compiled
    # inside it, and no Python
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm (binutils) not installed")
    fmu3 = pairs["GuidedNetworkOperatorController"][1]
    lib = tmp_path / "lib.so"
    with zipfile.ZipFile(fmu3) as z:
        (so,) = [n for n in z.namelist() if n.startswith("binaries/")]
        lib.write_bytes(z.read(so))
    dyn = subprocess.run([nm, "-D", "--defined-only", str(lib)], capture_output=True, text=True,
                         check=True).stdout
    exported = {line.split()[-1] for line in dyn.splitlines() if " T " in line}
    header = (Path(c_file("fmi3Functions.h"))).read_text()
    declared = set(re.findall(r"^#define (fmi3\w+)\s+fmi3FullName", header, re.M))
    assert len(declared) == 75 and exported == declared
    assert not any("Py" in line or "python" in line.lower() for line in dyn.splitlines())


def _columns(result) -> dict:
    return {n: result[n].tobytes() for n in result.dtype.names}


def _simulate(fmu: Path, **kwargs):
    """fmpy's result, or the error it raised (the two versions must fail alike)."""
    try:
        return _columns(simulate_fmu(str(fmu), **kwargs))
    except Exception as exc:                       # compared as text between the versions
        return f"{type(exc).__name__}: {exc}".replace("fmi3", "fmi?").replace("fmi2", "fmi?")


def test_variants_fly_as_fmi2_bitwise(pairs):
    # every FMU from its declared start values and inputs, 40 s at 0.5 s output points: the
    # plants fly, the controllers hold or sample their (constant) inputs
    for name, (fmu2, fmu3) in pairs.items():
        a = _simulate(fmu2, stop_time=40.0, output_interval=0.5)
        b = _simulate(fmu3, stop_time=40.0, output_interval=0.5)
        assert isinstance(a, dict), f"{name}: {a}"
        assert a == b, name


def _fed(spec, fmu_dir):
    """The native FMI 2.0 closed loop of ``spec`` flown by the package's master, recorded: the
    signals each component received at every communication point."""
    native = fmu_dir / "native"
    w = spec.wiring
    ctrl = native / (f"{w.name}Controller.fmu" if spec.controller_defaults is not None
                     else f"{w.controller}.fmu")
    loop = ClosedLoop(w, native / f"{w.plant}.fmu", ctrl)
    try:
        rec = loop.run(record=True)
    finally:
        loop.close()

    def table(pairs_, key):
        names = [(key(a), b) for a, b in pairs_]
        arr = np.zeros(len(rec.time), dtype=[("time", float)] + [(b, float) for _, b in names])
        arr["time"] = rec.time
        for a, b in names:
            arr[b] = rec.outputs[a]
        return arr
    return (w, native / f"{w.plant}.fmu", table(w.to_plant, lambda a: "ctrl." + a), ctrl,
            table(w.to_controller, lambda a: a), rec.time[-1])


def _check_loop(spec, fmu_dir, fmi3_of):
    w, plant, u, ctrl, y, t_end = _fed(spec, fmu_dir)
    for fmu, signal in ((plant, u), (ctrl, y)):
        kwargs = dict(stop_time=float(t_end), output_interval=w.step, input=signal)
        a, b = _simulate(fmu, **kwargs), _simulate(fmi3_of(fmu), **kwargs)
        assert isinstance(a, dict), f"{fmu.name}: {a}"
        assert a == b, f"{w.name}: {fmu.name}"


def test_every_native_loop_component_flies_as_fmi2_bitwise(pairs, fmu_dir):
    # each native closed loop's plant fed the controls, its controller fed the plant's
    # outputs, as recorded in the FMI 2.0 loop: every output at every point equal
    specs = [s for s in closed_loop_specs() if (fmu_dir / "native" / f"{s.wiring.name}.ssp")
             .is_file()]
    assert len(specs) >= 7
    for spec in specs:
        _check_loop(spec, fmu_dir, lambda fmu: pairs[fmu.stem][1])


# -- what a user sees -----------------------------------------------------------------------
def _fmpy_cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fmpy", *map(str, args)], capture_output=True,
                          text=True, timeout=120)


def _csv_of_fmi2_and_fmi3(fmu2, fmu3, folder: Path, *options) -> tuple:
    """``fmpy simulate`` of both FMUs with ``options``: their CSV files' bytes."""
    out = []
    for fmu, csv in ((fmu2, folder / "two.csv"), (fmu3, folder / "three.csv")):
        res = _fmpy_cli("simulate", fmu, *options, "--output-file", csv)
        assert res.returncode == 0, res.stderr
        out.append(csv.read_bytes())
    return tuple(out)


def _refused_start_value(fmu, name: str, value: str) -> str:
    """``fmpy simulate`` with a bad start value (no --debug-logging): it fails; what it printed."""
    res = _fmpy_cli("simulate", fmu, "--start-values", name, value)
    assert res.returncode != 0
    return res.stdout


def test_fmpy_simulate_cli(pairs, tmp_path):
    # the fmpy command line runs a variant (the same CSV as the FMI 2.0 FMU's, to the byte)
    # and prints a bad start value's message without --debug-logging
    fmu2, fmu3 = pairs["Reentry"]
    two, three = _csv_of_fmi2_and_fmi3(fmu2, fmu3, tmp_path, "--stop-time", "30")
    assert three == two
    assert "[ERROR] Reentry: parameter m must be > 0, got -5.0" in \
        _refused_start_value(fmu3, "m", "-5")


def test_fmpy_compile_rebuilds_a_variant(pairs, tmp_path):
    # another tool's build of the shipped sources (fmpy compile: CMake and the FMI 3.0
    # sources/buildDescription.xml) flies as the FMI 2.0 FMU, bitwise
    if shutil.which("cmake") is None:
        pytest.skip("cmake not installed (fmpy compile needs it; CI installs it)")
    fmu2, fmu3 = pairs["Reentry"]
    rebuilt = tmp_path / "Reentry.fmu"
    rebuilt.write_bytes(fmu3.read_bytes())
    binary = f"binaries/{platform_tuple()}/Reentry{platform_folder()[1]}"
    with zipfile.ZipFile(rebuilt) as z:
        before = z.read(binary)
    res = _fmpy_cli("compile", rebuilt)
    assert res.returncode == 0, res.stderr[-2000:]
    with zipfile.ZipFile(rebuilt) as z:
        assert z.read(binary) != before               # CMake's build, not ours
    kwargs = dict(stop_time=30.0, output_interval=0.5)
    assert _simulate(rebuilt, **kwargs) == _simulate(fmu2, **kwargs)


class _Host:
    """An FMI 3.0 instance driven call by call, its messages collected."""

    def __init__(self, fmu: Path, tmp: Path, token: str | None = None):
        md = read_model_description(str(fmu))
        unzipped = tmp / fmu.stem
        with zipfile.ZipFile(fmu) as z:
            z.extractall(unzipped)
        self.messages = []
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.slave = FMU3Slave(guid=token or md.instantiationToken, unzipDirectory=str(unzipped),
                               modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName="probe")

    def instantiate(self) -> bool:
        def log(env, status, category, message):
            self.messages.append((status, message.decode()))
        try:
            self.slave.instantiate(logMessage=log)
            return True
        except Exception:               # fmpy: "Failed to instantiate FMU"
            return False

    def status(self, fn, *args) -> int:
        """The status of the FMI 3.0 call ``fn`` (fmpy's method), not raised."""
        try:
            getattr(self.slave, fn)(*args)
            return 0
        except FMICallException as exc:
            return exc.status


def test_fmi3_calls_and_messages(pairs, tmp_path):
    # the calls the FMI 3.0 wrapper adds to the FMI 2.0 one: the instantiation token, the
    # independent variable time, the types and features it has not (each an error that says so)
    fmu3 = pairs["NetworkOperatorController"][1]
    bad = _Host(fmu3, tmp_path / "bad", token="{00000000-0000-0000-0000-000000000000}")
    assert not bad.instantiate()
    assert bad.messages and bad.messages[0][0] == 3
    assert "wrong GUID {00000000-0000-0000-0000-000000000000}" in bad.messages[0][1]

    host = _Host(fmu3, tmp_path / "good")
    assert host.instantiate()
    s, t = host.slave, host.vr["time"]
    s.enterInitializationMode(startTime=2.0)
    s.exitInitializationMode()
    assert s.getFloat64([t]) == [2.0]
    s.doStep(2.0, 0.75)
    assert s.getFloat64([t, host.vr["u[1]"]])[0] == 2.75
    del host.messages[:]
    assert host.status("setFloat64", [t], [1.0]) == 3
    assert host.status("getFMUState") == 3
    assert host.status("setBoolean", [0], [True]) == 3
    assert host.status("getFloat32", []) == 0             # asked for nothing: fine
    assert [m for _, m in host.messages] == [
        f"probe: value reference {t} is the independent variable time and cannot be set",
        "probe: fmi3GetFMUState is not supported by this FMU",
        "probe: this FMU has no Boolean variables"]
    s.terminate()
    s.freeInstance()


def test_variant_reads_back_the_variable_table(fmu_dir, tmp_path):
    # the FMI 2.0 description gives back the table it was written from, and the variant's
    # description is the FMI 3.0 writer's on that table
    law = NetworkOperator.load(REENTRY_LAW)
    fmu2 = build_law_fmu(law, tmp_path / "Law.fmu", "Law", "a law", ["u = ..."])
    with zipfile.ZipFile(fmu2) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    assert variables_of(md) == law_variables(law)
    fmu3 = fmi3_variant(fmu2, tmp_path / "fmi3" / "Law.fmu")
    with zipfile.ZipFile(fmu3) as z:
        written = z.read("modelDescription.xml")
    assert written == model_description("Law", md.get("guid"), md.get("description"),
                                        fmi3_rows(law_variables(law)), None,
                                        FMI3_GENERATION_TOOL)
    for other in (fmu3, fmu_dir / "Reentry.fmu"):       # an FMI 3.0, a pythonfmu FMU (a closed
        with pytest.raises(NotNativeError, match="is not a native FMI 2.0 FMU of descent-fmus"):
            fmi3_variant(other, tmp_path / "again.fmu")    # loop: test_loop_fmi3.py)


def test_a_variant_reuses_its_twins_objects(tmp_path):
    # within reusing_objects() (build_fmus.py) the model's objects of the FMI 2.0 build are
    # kept and the variant compiles none of them again; they are dropped at the end
    from descent_fmus.synthesis.fmi.native.builders import build
    law = NetworkOperator.load(REENTRY_LAW)
    with build.reusing_objects():
        fmu2 = build_law_fmu(law, tmp_path / "Law.fmu", "Law")
        kept = set(build._MODEL_KEYS)
        objects = [build._OBJECTS[k] for k in kept]
        assert len(kept) == 2                           # law_model.c and law.c
        fmi3_variant(fmu2, tmp_path / "fmi3" / "Law.fmu")
        assert build._MODEL_KEYS == kept
    assert not build._MODEL_KEYS and not any(o.exists() for o in objects)
    kwargs = dict(stop_time=3.0, output_interval=1.0)
    assert _simulate(tmp_path / "fmi3" / "Law.fmu", **kwargs) == _simulate(fmu2, **kwargs)


def test_export_law_fmi3(fmu_dir, tmp_path, capsys):
    out = tmp_path / "law"
    assert main(["export-law", str(REENTRY_LAW), "--native", "--fmi3", "--out", str(out),
                 "--name", "BestLaw", "--fmus", str(fmu_dir), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["controller_fmu_fmi3"] == str(out / "fmi3" / "BestLaw.fmu")
    fmu2, fmu3 = out / "BestLaw.fmu", out / "fmi3" / "BestLaw.fmu"
    assert validate_fmu(str(fmu3)) == []
    # the interpreter law's start values (the law itself) go with the variant, which reads them
    # (the law below flies as the FMI 2.0 FMU's; the interpreter's compiled starts do not)
    with zipfile.ZipFile(fmu2) as z2, zipfile.ZipFile(fmu3) as z3:
        assert z3.read("resources/start_values.txt") == z2.read("resources/start_values.txt")
    # the law of y1, y2 over a grid of inputs: the same u, bitwise
    grid = np.zeros(41, dtype=[("time", float), ("x[1]", float), ("x[2]", float)])
    grid["time"] = np.arange(41.0)
    grid["x[1]"] = np.linspace(-0.05, 0.05, 41)
    grid["x[2]"] = np.linspace(-1.0, 0.2, 41)
    kwargs = dict(stop_time=40.0, output_interval=1.0, input=grid)
    assert _simulate(fmu3, **kwargs) == _simulate(fmu2, **kwargs)
    # --fmi3 with a pythonfmu law FMU: one line, exit 2, nothing written
    bad = tmp_path / "py"
    assert main(["export-law", str(REENTRY_LAW), "--python", "--fmi3", "--out", str(bad),
                 "--fmus", str(fmu_dir)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--fmi3 needs the native law FMU" in err and len(err.splitlines()) == 1
    assert not bad.exists()


def test_fmi3_variant_command(hopper_dir, tmp_path, capsys):
    # a user's plant (the tutorial's hopper, build-plant's native twin) as FMI 3.0: it flies as
    # its FMI 2.0 twin, bitwise; bad input is one line, exit 2, nothing written
    out = tmp_path / "Hopper3.fmu"
    assert main(["fmi3-variant", str(hopper_dir / "native" / "Hopper.fmu"), "--out", str(out),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["out"] == str(out)
    kwargs = dict(stop_time=5.0, output_interval=0.1)
    assert _simulate(out, **kwargs) == _simulate(hopper_dir / "native" / "Hopper.fmu", **kwargs)
    for argv in ([str(hopper_dir / "Hopper.fmu"), "--out", str(tmp_path / "a.fmu")],
                 [str(tmp_path / "none.fmu"), "--out", str(tmp_path / "b.fmu")],
                 [str(hopper_dir / "native" / "Hopper.fmu"), "--out", str(out)]):
        assert main(["fmi3-variant", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err, argv
    assert not (tmp_path / "a.fmu").exists() and not (tmp_path / "b.fmu").exists()
