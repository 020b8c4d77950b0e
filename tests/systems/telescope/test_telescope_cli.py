"""``descent-fmus telescope reorient | route | write-programs`` and the system package.

Sources: Voronov (2009), Example 1 (5 iterations to 1e-7) and Example 3 (the route, eps), the
stored programs (a fresh solve must reproduce them), the closed-form reach of a rate limit.
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from descent_fmus.synthesis.cli.main import main


def test_reorient_json_and_no_file_without_plot(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["telescope", "reorient", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    # Voronov (2009), Example 1: 5 iterations to 1e-7
    assert s["iterations"] <= 5 and max(map(abs, s["final_errors"].values())) < 1e-7
    assert "plot" not in s
    assert list(tmp_path.iterdir()) == []                 # nothing written unless asked


def test_reorient_plot_writes_one_png(capsys, tmp_path):
    path = tmp_path / "reorient.png"
    assert main(["telescope", "reorient", "--plot", str(path)]) == 0
    assert f"plot: {path}" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == [path] and path.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv, message", [
    (["--w-final", "0", "0", "5"], "unreachable target"),
    (["--h", "-1"], "parameter h must be > 0"),
    (["--replay", "--fmus", "/nonexistent"], "FMU not found"),
])
def test_user_errors_are_one_line_exit_2(capsys, argv, message):
    assert main(["telescope", "reorient"] + argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_reorient_with_a_gimbal_rate_limit(capsys):
    assert main(["telescope", "reorient", "--u-max", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    # the default limit 0.1 rad/s binds (unconstrained peak 0.137), end accuracy 1e-7 kept
    assert s["u_max"] == 0.1 and s["u_max_abs"] <= 0.1
    assert max(map(abs, s["final_errors"].values())) < 1e-7


@pytest.mark.parametrize("argv, message", [
    (["reorient", "--u-max", "0.003"], "too small"),             # closed form, no iteration
    (["reorient", "--u-max", "0.02"], "too small"),              # bounded iterations
    (["route", "--w0", "0", "0.3", "0"], "starts away from the initial state"),
    (["route", "--u-max", "0.005"], "too small for the route"),
])
def test_rate_limit_and_route_errors_are_one_line_and_write_nothing(capsys, tmp_path, argv,
                                                                     message):
    plot = tmp_path / "out.png"
    assert main(["telescope"] + argv + ["--plot", str(plot)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_route_json_and_plot(capsys, tmp_path):
    path = tmp_path / "route.png"
    assert main(["telescope", "route", "--eps", "1e-3", "--rule", "adaptive", "--json",
                 "--plot", str(path)]) == 0
    s = json.loads(capsys.readouterr().out)
    # a looser neighbourhood than Example 3's (5e-5) needs few stages; every deviation within it
    assert s["eps"] == 1e-3 and s["max_deviation"] <= 1e-3 and s["max_relative_deviation"] <= 1
    assert s["rule"] == "adaptive" and s["joints"] == "continuous"
    assert 1 <= s["stages"] <= s["paper_stages"] and s["tau"][0] == 0 and s["tau"][-1] == 80
    assert s["plot"] == str(path) and list(tmp_path.iterdir()) == [path]
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_bad_option_values_are_refused_by_the_parser(capsys):
    for argv in (["reorient", "--T", "-5"], ["reorient", "--tol", "0"],
                 ["reorient", "--max-iter", "0"], ["reorient", "--u-max", "-0.1"],
                 ["route", "--eps", "0"], ["route", "--eps", "-1e-5"], ["route", "--rule", "x"],
                 ["route", "--intervals", "1"]):
        with pytest.raises(SystemExit) as exc:
            main(["telescope"] + argv)
        assert exc.value.code == 2
    capsys.readouterr()


def test_write_programs_reproduces_the_stored_programs(capsys, tmp_path):
    from descent_fmus.synthesis.systems.telescope.wiring import stored_programs
    out = tmp_path / "programs.json"
    assert main(["telescope", "write-programs", "--out", str(out), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["programs"] == str(out) and s["models"]["rigid"]["n_nodes"] == 41
    # oracle: the stored programs (the closed-loop FMUs' defaults) are a fresh solve's output
    fresh, stored = stored_programs(out), stored_programs()
    for model in ("rigid", "flexible"):
        assert fresh[model].keys() == stored[model].keys()
        assert max(abs(fresh[model][k] - stored[model][k]) for k in stored[model]) < 1e-12


def test_importing_the_system_does_no_work():
    # no solving (scipy.integrate, matplotlib), no data file read: the programs are read only
    # when a closed-loop FMU is built
    code = ("import builtins, io, sys\n"
            "opened = []\n"
            "real_open = io.open\n"
            "def spy(file, *a, **k):\n"
            "    opened.append(str(file))\n"
            "    return real_open(file, *a, **k)\n"
            "builtins.open = io.open = spy\n"
            "from descent_fmus.synthesis.registry import get_system\n"
            "system = get_system('telescope')\n"
            "print(system.stem, 'scipy.integrate' in sys.modules, 'matplotlib' in sys.modules,\n"
            "      any(f.endswith('.json') for f in opened))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["telescope", "False", "False", "False"]
