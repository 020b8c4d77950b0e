"""S3 lunar landing: the ``descent-fmus lunar-landing solve | fly`` commands and the system record.

Sources (named per test): Mozzhorina (2017) Table 2; the closed-form optimum ``optimal_landing``.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from descent_fmus.models.integrators import REACHED
from descent_fmus.models.lunar_landing import LanderParams
from descent_fmus.models.params import description_of
from descent_fmus.synthesis.cli.main import main
from descent_fmus.synthesis.systems.lunar_landing.problems import PAPER_TABLE2


def test_solve_json_plot_and_errors(capsys, tmp_path):
    # Mozzhorina (2017) Table 2 (T) and the closed form (relative error of the fuel)
    assert main(["lunar-landing", "solve", "--json", "--plot", str(tmp_path / "fig.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert round(out["T"], 4) == PAPER_TABLE2["T"]
    assert out["relative_error"]["fuel"] < 1e-8
    assert (tmp_path / "fig.png").stat().st_size > 10_000
    assert main(["lunar-landing", "solve", "--umax", "7"]) == 2
    err = capsys.readouterr().err
    assert "cannot even hold" in err and err.count("\n") == 1
    assert main(["lunar-landing", "solve", "--guess", "-0.1", "-0.1", "15"]) == 2
    err = capsys.readouterr().err
    assert "never switches" in err and "Traceback" not in err and err.count("\n") == 1
    assert main(["lunar-landing", "solve", "--guess", "-0.1", "auto", "10", "--method",
                 "interpolate"]) == 0
    assert math.isfinite(float(capsys.readouterr().out.split("T [s]")[1].split()[0]))
    assert main(["lunar-landing", "solve", "--guess", "auto", "-0.7", "15"]) == 2
    assert "only PSI3 may be 'auto'" in capsys.readouterr().err


def test_solve_json_writes_nothing(capsys, tmp_path, monkeypatch):
    # no file is written unless --plot names one (the old command wrote lunar_landing.png)
    monkeypatch.chdir(tmp_path)
    assert main(["lunar-landing", "solve", "--json", "--table1"]) == 0
    out = json.loads(capsys.readouterr().out)
    # Mozzhorina (2017) Table 1: 4, 6, 5 iterations; the event method takes 4, 5, 5 (README)
    assert [row["classical"] for row in out["table1"]] == [4, 5, 5]
    assert [row["paper"] for row in out["table1"]] == [4, 6, 5]
    assert "plot" not in out
    assert list(tmp_path.iterdir()) == []


def test_plant_options_come_from_the_parameter_dataclass(capsys):
    with pytest.raises(SystemExit):
        main(["lunar-landing", "solve", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name in ("umax", "h0", "V0"):
        default = getattr(LanderParams(), name)
        assert f"{description_of(LanderParams, name)} (default {default:g})" in text
    assert "(default 14.57)" in text


def test_fly_json_plot_and_errors(capsys, tmp_path, monkeypatch, fmu_dir):
    # acceptance |V| < 0.05 m/s at touchdown for both laws (models/README.md)
    monkeypatch.chdir(tmp_path)
    assert main(["lunar-landing", "fly", "--json", "--fmus", str(fmu_dir)]) == 0
    out = json.loads(capsys.readouterr().out)
    for law in ("program", "feedback"):
        td = out["closed_loop"][law]
        assert td["status"] == REACHED and td["soft"] and abs(td["V_touchdown"]) < 0.05
    assert list(tmp_path.iterdir()) == []
    assert main(["lunar-landing", "fly", "--json", "--fmus", str(fmu_dir), "--dispersion", "1",
                 "--plot", "disp.png"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["dispersion"]["laws"]["feedback"]["runs"] == 1 + 8
    assert out["dispersion"]["laws"]["feedback"]["soft"] == 1 + 8
    assert (tmp_path / "disp.png").stat().st_size > 10_000
    assert main(["lunar-landing", "fly", "--plot", "x.png", "--fmus", str(fmu_dir)]) == 2
    assert "--dispersion" in capsys.readouterr().err
    assert main(["lunar-landing", "fly", "--h0", "-5", "--fmus", str(fmu_dir)]) == 2
    err = capsys.readouterr().err
    assert "h0 must be >= 0" in err and err.count("\n") == 1
    assert main(["lunar-landing", "fly", "--fmus", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert "FMU not found" in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disp.png"]


def test_system_record():
    from descent_fmus.synthesis.registry import get_system
    s = get_system("lunar-landing")
    assert s.stem == "lunar_landing" and s.cli_name == "lunar-landing"
    assert s.fmus == ("lunar_landing:LunarLander",
                      "controllers.lunar_landing_program:LandingProgram",
                      "controllers.lunar_landing_switch:LandingSwitch")
    names = [c.wiring.name for c in s.closed_loops]
    assert names == ["LunarLanderProgramClosedLoop", "LunarLanderFeedbackClosedLoop"]
    assert callable(s.closed_loops[0].controller_defaults)
    assert s.closed_loops[1].controller_defaults is None


IMPORT_CHECK = """
import sys
import descent_fmus.models.lunar_landing as model
def forbidden(*args, **kwargs):
    raise SystemExit("optimal_landing called at import time")
model.optimal_landing = forbidden
import descent_fmus.synthesis.systems.lunar_landing as pkg
assert pkg.SYSTEM.stem == "lunar_landing"
heavy = [m for m in ("scipy.integrate", "scipy.optimize", "matplotlib") if m in sys.modules]
print("heavy:", heavy)
"""


def test_importing_the_system_does_no_work():
    # no solve (optimal_landing is not called), no SciPy integration, no plotting at import
    out = subprocess.run([sys.executable, "-c", IMPORT_CHECK], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "heavy: []" in out.stdout
