"""``descent-fmus build-plant``: a plant written once -> its pythonfmu FMU and its native twin.

Oracles: the closed form of the tiny plant's free motion (exponential decay; RK4 on 0.01 s
sub-steps is exact to ~1e-12 there) for the pythonfmu FMU; that FMU itself, flown here through
the same FMI calls, for the native twin (every output at every communication point, bitwise);
a deliberately different FMU for the check (it must report the difference); fmpy's validation;
the closed-form touchdown of the tutorial's hopper in free fall (RK4 is exact for its quadratic
height); the pythonfmu path of the same problem for the native path (the same objectives).
"""
from __future__ import annotations

import math
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from descent_fmus.synthesis.fmi.native.builders.build import find_compiler
from descent_fmus.synthesis.fmi.user_plant import (PlantFileError, build_plant,
                                                          check_twins)

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (CI installs gcc)")

ROOT = Path(__file__).resolve().parents[2]

#: a tiny plant in the model style: a damped spinner, the angle reported wrapped by math.fmod
SPINNER = '''
"""A damped spinner: th' = w, w' = u - c w (u clipped to [-1, 1], NaN: 0)."""
import math
from dataclasses import dataclass

from descent_fmus.models.fmu_support import SlaveBase
from descent_fmus.models.integrators import DIVERGED, LEFT_DOMAIN, Integrator, advance_to
from descent_fmus.models.params import Params, param
from descent_fmus.models.traceable import clip, where


@dataclass(frozen=True)
class SpinnerParams(Params):
    th0: float = param(0.5, "rad", "initial angle")
    w0: float = param(DEFAULT_W0, "rad/s", "initial rate")
    c: float = param(0.8, "1/s", "damping", positive=True)


def rhs(x, u, c):
    th, w = x
    return (w, u - c * w)


class SpinnerIntegrator(Integrator):
    def __init__(self, p, dt):
        self.p = p.validate()
        super().__init__(dt)

    def initial_state(self):
        return (self.p.th0, self.p.w0)

    def advance(self, t_end, u):
        if self.status:
            return
        x, t, outcome = advance_to(rhs, self.x, self.t, t_end, self.dt, (u, self.p.c))
        self.x, self.t = x, t
        if outcome == DIVERGED:
            self.end(LEFT_DOMAIN, t)


class Spinner(SlaveBase):
    description = "a damped spinner (test plant)"
    params_class = SpinnerParams

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.parameters()
        self.parameter("dt", 0.01, "RK4 sub-step [s]")
        self.input("u", 0.0, "torque, clipped to [-1, 1] [1/s2]")
        self.output("th", "angle in (-2 pi, 2 pi) [rad]",
                    getter=lambda: math.fmod(self._ig.x[0], 2.0 * math.pi))
        self.output("w", "rate [rad/s]", getter=lambda: self._ig.x[1])
        self.output("turns", "angle / 2 pi [1]", getter=lambda: self._ig.x[0] / (2.0 * math.pi))
        self.status_outputs(lambda: self._ig.status, lambda: self._ig.t_end_output)
        self.prepare()

    def prepare(self):
        self._ig = SpinnerIntegrator(self.params(), self.dt)

    def do_step(self, current_time, step_size):
        u = self.u
        self._ig.advance(current_time + step_size,
                         where(u != u, 0.0, lambda: clip(u, -1.0, 1.0)))
        return True
'''


def spinner(tmp_path: Path, w0: float = 3.0, name: str = "spinner.py", body: str = SPINNER
            ) -> Path:
    path = tmp_path / name
    path.write_text(body.replace("DEFAULT_W0", repr(w0)))
    return path


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("spinner")
    return d, build_plant(spinner(d), d / "out")


def test_both_fmus_are_built_valid_and_bitwise_equal(built):
    d, r = built
    py, c = d / "out" / "Spinner.fmu", d / "out" / "native" / "Spinner.fmu"
    assert r["pythonfmu"] == str(py) and r["native"] == str(c) and py.is_file() and c.is_file()
    check = r["check"]
    assert check["equal"] and check["mismatch"] is None
    assert check["flights"] == 3 and check["points"] == 3 * 101 and check["outputs"] == 5
    assert r["validate"] == {str(py): [], str(c): []}
    # the native binary needs no Python
    import zipfile
    with zipfile.ZipFile(c) as z:
        assert not any("python" in n.lower() for n in z.namelist())


def test_the_pythonfmu_fmu_is_the_closed_form_and_the_twin_is_it_bitwise(built):
    # free motion (u = 0): w = w0 exp(-c t), th = th0 + w0 / c (1 - exp(-c t))
    from fmpy import simulate_fmu
    d, _ = built
    out = {}
    for kind, path in (("py", d / "out" / "Spinner.fmu"),
                       ("c", d / "out" / "native" / "Spinner.fmu")):
        out[kind] = simulate_fmu(str(path), stop_time=5.0, output_interval=0.1,
                                 start_values={"w0": 2.0, "c": 0.5}, output=["th", "w", "turns"])
    t = out["py"]["time"]
    w = 2.0 * math.e ** (-0.5 * t)
    th = 0.5 + 2.0 / 0.5 * (1.0 - math.e ** (-0.5 * t))
    assert max(abs(out["py"]["w"] - w)) < 1e-10
    assert max(abs(out["py"]["turns"] * 2 * math.pi - th)) < 1e-10
    assert max(abs(out["py"]["th"] - [math.fmod(a, 2 * math.pi) for a in th])) < 1e-10
    for name in ("th", "w", "turns"):
        assert out["py"][name].tobytes() == out["c"][name].tobytes(), name


def test_a_rebuild_after_an_edit_builds_the_edit(tmp_path):
    # one process, one plant file built, edited (another default w0) and built again: both
    # FMUs carry the edited default (oracle: the file's text).  The pythonfmu build imported
    # the plant's module by name, and a module of that name from the first build stood in
    from fmpy import read_model_description
    for w0 in (3.0, 5.5):
        r = build_plant(spinner(tmp_path, w0=w0), tmp_path / "out")
        assert r["check"]["equal"]
        for path in (r["pythonfmu"], r["native"]):
            v = {x.name: x for x in read_model_description(path).modelVariables}
            assert float(v["w0"].start) == w0, path


def test_a_description_ending_in_a_bracket_that_is_no_unit_builds(tmp_path):
    # a user described an output as "..., in [-inf, inf]": the bracket is text, not a unit
    # (the build failed on it, "cannot read unit factor"); both FMUs are built and valid, the
    # output has no unit and its description as written, the other units stay
    body = SPINNER.replace('"angle / 2 pi [1]"', '"angle / 2 pi, in [-inf, inf]"')
    assert body != SPINNER
    r = build_plant(spinner(tmp_path, body=body), tmp_path / "out")
    assert r["check"]["equal"] and all(v == [] for v in r["validate"].values())
    from fmpy import read_model_description
    for path in (r["pythonfmu"], r["native"]):
        v = {x.name: x for x in read_model_description(path).modelVariables}
        assert v["turns"].unit is None
        assert v["turns"].description == "angle / 2 pi, in [-inf, inf]"
        assert v["w"].unit == "rad/s" and v["u"].unit == "1/s2"


def test_the_check_reports_a_difference(built, tmp_path):
    # an FMU of another definition (a different default rate) is not the twin: the check says
    # where the flights first differ
    d, _ = built
    other = build_plant(spinner(tmp_path, w0=3.0000000000000004), tmp_path / "out", check=False,
                        validate=False)
    r = check_twins(d / "out" / "Spinner.fmu", other["native"], steps=10)
    assert not r["equal"]
    m = r["mismatch"]
    assert (m["time"], m["flight"], m["output"]) == (0.0, "held", "w")
    assert (m["pythonfmu"], m["native"]) == (3.0, 3.0000000000000004)


#: an untraceable right-hand side -> the words of its one-line error (the construct's line is
#: the one holding the first code line)
UNTRACEABLE = {
    "    return (w, u - c * w * int(th))": "int() of a traced value",
    "    return (w, u - (c * w) % 2.0)": "% of a traced value",
    "    while w > 0.0:\n        w = w - 1.0\n    return (w, u - c * w)": "more than 2000 decisions",
    "    return (w, u - c * math.erf(w))": "math.erf of a traced value",
}


@pytest.mark.parametrize("code", list(UNTRACEABLE))
def test_an_untraceable_construct_is_one_line_naming_it(tmp_path, code):
    body = SPINNER.replace("    return (w, u - c * w)", code, 1)
    path = spinner(tmp_path, body=body)
    lineno = body.splitlines().index(code.splitlines()[0]) + 1
    r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "build-plant",
                        str(path), "-d", str(tmp_path / "out")], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    msg = r.stderr.strip()
    assert "\n" not in msg and UNTRACEABLE[code] in msg, msg
    assert f"spinner.py:{lineno}: " in msg, msg
    assert not (tmp_path / "out").exists()          # nothing written


def test_a_pythonfmu_only_plant_is_told_the_model_style(tmp_path):
    old = tmp_path / "old.py"
    old.write_text(textwrap.dedent('''
        from pythonfmu import Fmi2Slave
        class Old(Fmi2Slave):
            def do_step(self, t, h):
                return True
    '''))
    with pytest.raises(PlantFileError) as exc:
        build_plant(old, tmp_path / "out")
    assert "Old derives pythonfmu's Fmi2Slave" in str(exc.value) and "SlaveBase" in str(exc.value)


# -- the tutorial's hopper through the new path ------------------------------------------------
def test_hopper_free_fall_touches_down_where_the_closed_form_says(hopper_dir):
    # h(t) = h0 + v0 t - g t^2 / 2 = 0 at T = (v0 + sqrt(v0^2 + 2 g h0)) / g, v(T) = v0 - g T
    from fmpy import simulate_fmu
    h0, v0, g = 10.0, -1.0, 1.62
    T = (v0 + math.sqrt(v0 * v0 + 2 * g * h0)) / g
    for path in (hopper_dir / "Hopper.fmu", hopper_dir / "native" / "Hopper.fmu"):
        r = simulate_fmu(str(path), stop_time=5.0, output_interval=0.1,
                         start_values={"h0": h0, "v0": v0}, output=["h", "v", "status", "t_end"])
        assert r["status"][-1] == 1 and r["h"][-1] == 0.0
        assert r["t_end"][-1] == pytest.approx(T, abs=1e-9)
        assert r["v"][-1] == pytest.approx(v0 - g * T, abs=1e-8)


def test_the_hopper_problem_flies_the_twin_with_the_pythonfmu_numbers(hopper_dir, fmu_dir,
                                                                       tmp_path):
    from dataclasses import replace

    from descent_fmus.synthesis.fmi.native_loop import missing_twins
    from descent_fmus.synthesis.problems.files import load_problem_file
    from descent_fmus.synthesis.run.backends import flight_path
    from descent_fmus.synthesis.run.evaluation import Evaluator
    problem = load_problem_file(hopper_dir / "hopper.toml", fmu_dir=fmu_dir)
    fmus = problem.fmu_paths(fmu_dir)
    assert flight_path(problem, fmus) == "native-c"
    assert missing_twins(problem.wiring, *fmus) is None
    laws = [problem.basic(), problem.basic().with_q([-12.0, -3.9, 0.32])]
    F = {}
    for native in (None, False):
        p = replace(problem, runner=replace(problem.runner, native=native))
        with Evaluator(p, fmu_dir) as ev:
            assert ev.path == ("native-c" if native is None else "master")
            F[native] = ev.evaluate(laws).F
    assert F[None].tobytes() == F[False].tobytes()
    # a copy of the pythonfmu FMU alone flies pythonfmu, and the run says why
    shutil.copy(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu")
    shutil.copy(hopper_dir / "hopper.toml", tmp_path / "hopper.toml")
    alone = load_problem_file(tmp_path / "hopper.toml", fmu_dir=fmu_dir)
    fmus = alone.fmu_paths(fmu_dir)
    assert flight_path(alone, fmus) == "master"
    note = missing_twins(alone.wiring, *fmus)
    assert "no native/Hopper.fmu beside Hopper.fmu" in note and "build-plant" in note
