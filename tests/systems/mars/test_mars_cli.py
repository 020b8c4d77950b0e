"""S2 Mars capsule: ``descent-fmus mars fly``, ``descent-fmus info mars`` and the system package.

Oracle of the numbers: the acceptance of Lyubimov & Kurkina (fig. 2: alpha_end < 0.01 rad with
the law), as in tests/systems/mars/test_mars_loop.py.
"""
from __future__ import annotations

import json
import subprocess
import sys

from descent_fmus.synthesis.cli.main import main


def _fly(*argv):
    return main(["mars", "fly", *argv])


def test_fly_json(fmu_dir, capsys):
    assert _fly("--json", "--fmus", str(fmu_dir)) == 0
    out = json.loads(capsys.readouterr().out)
    none, law = out["runs"]
    assert law["alpha_end"] < 0.01 and none["alpha_end"] >= 5 * law["alpha_end"]
    assert law["status"] == none["status"] == "reached" and law["reached_h_end"]
    assert out["ratio_uncontrolled_to_controlled"] == none["alpha_end"] / law["alpha_end"]
    assert _fly("--no-control", "--json", "--fmus", str(fmu_dir)) == 0
    assert len(json.loads(capsys.readouterr().out)["runs"]) == 1


def test_fly_writes_no_file_without_plot(fmu_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert _fly("--no-control", "--fmus", str(fmu_dir)) == 0
    assert "alpha_end" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
    png = tmp_path / "alpha.png"
    assert _fly("--formula", "both", "--alpha0", "0.3", "--plot", str(png), "--json",
                "--fmus", str(fmu_dir)) == 0
    out = json.loads(capsys.readouterr().out)
    assert png.stat().st_size > 0 and out["plot"] == str(png)
    assert [r["label"] for r in out["runs"]] == ["no control", "law, consistent root",
                                                 "law, paper root"]
    assert list(tmp_path.iterdir()) == [png]


def test_fly_bad_parameter_is_one_line_exit_2(fmu_dir, capsys):
    for argv, words in ((["--c", "-1"], "parameter c"), (["--omega-x", "0"], "omega_x"),
                        (["--alpha0", "2"], "alpha0")):
        assert _fly(*argv, "--fmus", str(fmu_dir)) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1 and "Traceback" not in err


def test_fly_missing_fmus(tmp_path, capsys):
    assert _fly("--fmus", str(tmp_path)) == 2
    err = capsys.readouterr().err
    assert "build_fmus.py" in err and err.count("\n") == 1


def test_info_lists_the_fmus_and_their_parameters(capsys):
    assert main(["info", "mars", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [f["fmu"] for f in info["fmus"]] == ["MarsCapsule", "MarsCapsule6DOF",
                                                "MarsBellmanController"]
    assert info["closed_loops"] == ["MarsClosedLoop"]
    law = {p["name"]: p for p in info["fmus"][2]["parameters"]}
    assert set(law) == {"b", "c", "theta1", "u_max", "formula"}


def test_importing_the_system_does_no_work():
    # importing the package defines the SYSTEM record only: it flies nothing, opens no file,
    # imports neither scipy.integrate nor matplotlib
    code = """
import builtins, sys
import descent_fmus.synthesis.fmi.closed_loop, descent_fmus.models.fmu_support
opened = []
real_open = builtins.open
builtins.open = lambda *a, **k: (opened.append(a[0]), real_open(*a, **k))[1]
import descent_fmus.synthesis.systems.mars as m
builtins.open = real_open
assert m.SYSTEM.stem == "mars", m.SYSTEM
print(opened, [k for k in ("scipy.integrate", "matplotlib") if k in sys.modules])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[] []"
