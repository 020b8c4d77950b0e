"""Reductions of expressions of signals in problem files (synthesis/problems/expressions.py).

Oracles: closed forms of the trapezoidal rule on synthetic flights (ClosedLoopResult objects
built here, no FMU), NumPy applied by hand to the same arrays, the values the implementation
before reductions of expressions gave (commit ad6e33b, stored below as hexadecimal floats and
re-derived by plain Python formulas), and, through the FMUs, a recorded flight of the tutorial
plant with the integral computed here from its arrays.
"""
from __future__ import annotations

import math
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult
from descent_fmus.synthesis.problems.expressions import Expression, ExpressionError
from descent_fmus.synthesis.problems.file_functions import FlightExpression
from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorials"
REENTRY = ROOT / "synthesis" / "systems" / "reentry" / "reentry.toml"
SIGNALS = {"x", "y", "h", "v", "m", "u1", "status"}
LAW = (("u1", "u[1]"),)


def flight(t, stopped=True, final=None, **signals):
    """A synthetic flight: ``signals`` recorded at times ``t`` (u1 as the controller's u[1]);
    final outputs the last recorded values unless given."""
    t = np.asarray(t, dtype=float)
    out = {("ctrl.u[1]" if k == "u1" else k): np.asarray(x, dtype=float)
           for k, x in signals.items()}
    fin = {k: float(x[-1]) for k, x in signals.items() if k != "u1" and len(x)}
    fin.update(final or {})
    return ClosedLoopResult(time=t, outputs=out, final=fin, stopped=stopped,
                            steps=max(len(t) - 1, 0), t_final=float(t[-1]) if len(t) else 0.0)


def value(source, r, signals=SIGNALS):
    return FlightExpression(Expression(source, signals), LAW, True, 0.0)(r)


# -- closed forms ------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [2, 3, 11, 101])
def test_integral_of_t_squared_is_the_trapezoid_closed_form(n):
    # trapezoid on n equal steps of t**2 over [0, 1]: 1/3 + h**2/6, h = 1/(n - 1)
    t = np.linspace(0.0, 1.0, n)
    r = flight(t, x=t)
    exact = 1.0 / 3.0 + 1.0 / (6.0 * (n - 1) ** 2)
    assert value("integral(x**2)", r) == pytest.approx(exact, rel=1e-13)
    assert value("mean(x**2)", r) == pytest.approx(exact, rel=1e-13)       # duration 1 s
    # on [0, 2] (t = 2s): mean = 4/3 + 4 h**2/6 with h = 1/(n-1) of s ...; integral twice that
    t2 = 2.0 * t
    r2 = flight(t2, x=t2)
    assert value("integral(x**2)", r2) == pytest.approx(8.0 * exact, rel=1e-13)
    assert value("mean(x**2)", r2) == pytest.approx(4.0 * exact, rel=1e-13)


def test_peaks_and_pointwise_functions():
    t = np.linspace(0.0, 1.0, 9)                 # sin(2 pi t) reaches +-1 at t = 1/4, 3/4
    r = flight(t, x=t, y=np.sin(2 * np.pi * t), v=3.0 * t, h=4.0 * t)
    assert value("max(abs(sin(2*pi*x)))", r) == pytest.approx(1.0, abs=1e-15)
    assert value("min(sin(2*pi*x))", r) == pytest.approx(-1.0, abs=1e-15)
    assert value("max(sqrt(v**2 + h**2))", r) == pytest.approx(5.0, rel=1e-15)   # 3-4-5
    assert value("max(abs(y))", r) == float(np.max(np.abs(np.sin(2 * np.pi * t))))
    # every pointwise function is NumPy's on the same array (oracle: NumPy by hand)
    for f in ("abs", "sqrt", "exp", "log", "sin", "cos", "tanh"):
        arg = 1.0 + t
        assert value(f"max({f}(1 + x))", r) == float(np.max(getattr(np, f)(arg))), f


def test_conditionals_comparisons_and_two_argument_min_max_pointwise():
    t = np.linspace(0.0, 1.0, 11)      # 0.5 is a grid point: the kinks fall on the grid, so
    r = flight(t, x=t - 0.5, y=t)      # the trapezoid is exact for these piecewise-linear e
    assert value("mean(x if x > 0 else 0)", r) == pytest.approx(1 / 8, rel=1e-14)
    assert value("integral(max(x, 0))", r) == pytest.approx(1 / 8, rel=1e-14)
    assert value("integral(min(y, 0.5))", r) == pytest.approx(3 / 8, rel=1e-14)
    assert value("integral(max(x, 0, y - 0.9))", r) == pytest.approx(1 / 8, rel=1e-14)
    # x > 0 at t = 0.6 ... 1.0: 0 at 0.5, 1 from 0.6: 0.05 + 0.4
    assert value("integral(x > 0)", r) == pytest.approx(0.45, rel=1e-14)
    # 1 at t = 0.2 ... 0.8, 0 at 0.1 and 0.9: 0.6 + two half steps of 0.1
    assert value("integral(-0.35 < x <= 0.35)", r) == pytest.approx(0.7, rel=1e-14)
    assert value("max(x == 0)", r) == 1.0 and value("min(x != 0)", r) == 0.0


def test_final_initial_law_outputs_and_special_names():
    t = np.linspace(0.0, 2.0, 5)
    u = np.array([0.5, -0.25, 0.75, 1.0, -2.0])
    r = flight(t, stopped=False, v=-t, h=10.0 - t, u1=u)
    assert value("final(abs(v) + 10*h)", r) == 2.0 + 80.0
    assert value("initial(3*h + 1)", r) == 31.0
    assert value("final(u1) + initial(u1)", r) == -1.5
    assert value("integral(u1**2)", r) == pytest.approx(
        0.5 * np.sum((u[1:] ** 2 + u[:-1] ** 2) * 0.5))
    assert value("max(u1 + h)", r) == 10.5
    assert value("mean(h * tf) + integral(stopped + v*0)", r) == pytest.approx(9.0 * 2.0)
    # final of plant outputs reads the plant's final outputs: a flight recorded at no point
    empty = flight([], final={"v": -3.0, "h": 0.5})
    assert value("final(abs(v) + 10*h)", empty) == 8.0
    assert value("abs(final(v)) + final(v*h)", empty) == 1.5
    for source in ("integral(h)", "initial(h)", "max(abs(v))", "final(u1)"):
        assert math.isnan(value(source, empty)), source


# -- disambiguation ----------------------------------------------------------------------------
@pytest.mark.parametrize("source,terms", [
    ("max(x)", ["max(x)"]),                                  # one argument naming a signal
    ("max(abs(x))", ["max(abs(x))"]),
    ("max(final(x), 0.5)", ["final(x)"]),                    # two arguments: the larger
    ("max(final(x), final(y), 2)", ["final(x)", "final(y)"]),
    ("min(max(x), max(y))", ["max(x)", "max(y)"]),
    ("integral(max(x, 0.5))", ["integral(max(x, 0.5))"]),    # two arguments: pointwise
    ("mean(min(x, y, 0))", ["mean(min(x, y, 0))"]),
])
def test_max_min_one_argument_reduces_two_compare(source, terms):
    assert [str(r) for r in Expression(source, SIGNALS).terms] == terms


def test_disambiguation_values():
    t = np.linspace(0.0, 1.0, 5)
    r = flight(t, x=np.array([0.0, 2.0, 1.0, 0.25, 0.1]), y=np.zeros(5))
    assert value("max(x)", r) == 2.0
    assert value("max(final(x), 0.5)", r) == 0.5           # the larger of two numbers
    assert value("max(final(x), final(y), -2)", r) == 0.1
    assert value("max(max(x, 1))", r) == 2.0 and value("min(max(x, 1))", r) == 1.0


# -- errors ------------------------------------------------------------------------------------
ERRORS = [
    ("max(integral(x))", ["integral() inside max()", "a reduction inside a reduction"]),
    ("integral(max(x))", ["max() inside integral()"]),
    ("max(final(x))", ["final() inside max()"]),
    ("mean(x if final(y) > 0 else 0)", ["final() inside mean()"]),
    ("x + 1", ["signal 'x' must be reduced to a number", "final(x)"]),
    ("max(x, 0)", ["signal 'x' must be reduced"]),
    ("final(xx)", ["unknown signal 'xx' in final()", "known: h, m, status, u1, v, x, y"]),
    ("integral(x) + tt", ["unknown name 'tt'"]),
    ("integral(foo(x))", ["unknown function 'foo'", "allowed: abs, cos"]),
    ("max(3)", ["max() reduces an expression of the flight's signals", "'3' names none",
                "two or more arguments"]),
    ("integral(tf)", ["integral() reduces", "'tf' names none"]),
    ("final()", ["final() takes one argument", "got 0"]),
    ("integral(x, y)", ["integral() takes one argument", "got 2"]),
    ("max()", ["max() takes one argument (its maximum over the flight) or two or more"]),
    ("abs(final(x), 2)", ["abs() takes one argument, got 2"]),
    ("sqrt()", ["sqrt() takes one argument, got 0"]),
    ("mean(x, key=1)", ["without keywords"]),
    ("final(x).real", ["construct not allowed", "Attribute"]),
    ("__import__('os').system('ls')", ["allowed functions"]),
    ("final(x) + 'a'", ["only numbers are allowed as constants"]),
    ("final(x) +", ["syntax error"]),
    ("+".join(["final(x)"] * 5000), ["nested too deeply"]),
]


@pytest.mark.parametrize("source,words", ERRORS, ids=[e[1][0] for e in ERRORS])
def test_every_error_is_one_line(source, words):
    with pytest.raises(ExpressionError) as exc:
        Expression(source, SIGNALS)
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


# -- values that cannot be computed ------------------------------------------------------------
@pytest.mark.filterwarnings("error")
def test_uncomputable_values_are_nan_without_warnings():
    t = np.linspace(0.0, 1.0, 5)
    r = flight(t, x=t, y=t - 0.5)
    for source in ("max(log(x))", "integral(1/x)", "mean(exp(1000*x + 1000))",
                   "max(sqrt(y))", "integral(y**0.5)", "max((x + 1)**1e300)", "min(0/x)",
                   "final(log(x - 1))", "log(final(x) - 1)", "max(x) + 10**10**10"):
        assert math.isnan(value(source, r)), source
    # both branches are computed, the one not taken is dropped
    assert math.isfinite(value("mean(log(x) if x > 0 else 0)", r))
    assert math.isfinite(value("max(1/y if y != 0 else 0)", r))


def test_a_nan_is_the_problems_penalty(hopper_dir, fmu_dir, tmp_path):
    problem = load_problem_file(_hopper_with(hopper_dir, tmp_path, "max(log(h))"),
                                fmu_dir=fmu_dir)
    t = np.linspace(0.0, 1.0, 5)
    r = flight(t, h=t, v=-t, m=100.0 - t, fuel=t)    # log(0) at t = 0: NaN, the penalty
    outcome = problem.evaluate([r])
    assert outcome.f == problem.penalty and outcome.extras["failed"] == "non-finite objectives"


# -- every existing file means what it meant ---------------------------------------------------
def hopper_flight(n=26, tf=2.5, stopped=True):
    """The synthetic tutorial flight the values below were computed on (as at ad6e33b)."""
    t = np.linspace(0.0, tf, n)
    h = 10.0 - 0.8 * t ** 2 + 0.1 * np.sin(3.0 * t)
    v = -1.6 * t + 0.3 * np.cos(3.0 * t)
    m = 100.0 - 0.37 * t - 0.01 * t ** 2
    u = 0.324 - 0.15 * h - 0.5 * v
    return ClosedLoopResult(time=t, outputs={"h": h, "v": v, "m": m, "ctrl.u[1]": u},
                            final={"h": float(h[-1]), "v": float(v[-1]), "m": float(m[-1])},
                            stopped=stopped, steps=n - 1, t_final=float(t[-1]),
                            start={"h0": 10.0, "v0": 0.3})


def reentry_final(status, L, h, load_max):
    """A reentry flight recorded at no point (the file's objectives read final outputs)."""
    return ClosedLoopResult(time=np.array([]), outputs={},
                            final={"status": status, "L": L, "h": h, "load_max": load_max,
                                   "y1": 0.2, "y2": -0.2},
                            stopped=status != 0, steps=300, t_final=300.0)


HOPPER_FLIGHTS = (hopper_flight(), hopper_flight(n=7, tf=1.3, stopped=False))
REENTRY_FLIGHTS = (reentry_final(1, 1398765.4321, 9000.5, 8.5321),
                   reentry_final(2, 1234567.89, 15000.25, 12.75),
                   reentry_final(2, 1234567.89, 5000.25, 12.75))
J2 = ("abs(final(L) - 1400000.0) if final(status) == 1 else 2.0e7 + abs(1400000.0 - final(L)) "
      "+ max(final(h) - 10000.0, 0.0)")
#: (expression, flights, values at commit ad6e33b (float.hex), plain-Python oracle)
BEFORE = [
    ("abs(final(v))", HOPPER_FLIGHTS, ["0x1.f2b06fa8f0625p+1", "0x1.261da519affb5p+1"],
     lambda r: abs(r.final["v"])),
    ("initial(m) - final(m)", HOPPER_FLIGHTS, ["0x1.f999999999980p-1", "0x1.fdd97f62b6b00p-2"],
     lambda r: float(r["m"][0]) - r.final["m"]),
    ("final(load_max)", REENTRY_FLIGHTS, ["0x1.1106f69446738p+3", "0x1.9800000000000p+3",
                                          "0x1.9800000000000p+3"],
     lambda r: r.final["load_max"]),
    (J2, REENTRY_FLIGHTS, ["0x1.34a458793dc00p+10", "0x1.33c6c05c28f5cp+24",
                           "0x1.33b3381c28f5cp+24"],
     lambda r: (abs(r.final["L"] - 1400000.0) if r.final["status"] == 1 else
                2.0e7 + abs(1400000.0 - r.final["L"]) + max(r.final["h"] - 10000.0, 0.0))),
    # the other forms the language had (values at ad6e33b; NaN where it could not compute)
    ("integral(h)", HOPPER_FLIGHTS, ["0x1.4da0374c3868bp+4", "0x1.8ec48134ab305p+3"], None),
    ("mean(v)", HOPPER_FLIGHTS, ["-0x1.f6778f139c4b8p+0", "-0x1.174daf8837cb6p+0"], None),
    ("max(h) - min(h)", HOPPER_FLIGHTS, ["0x1.3b9000c8f6b50p+2", "0x1.7198eccf75770p+0"],
     lambda r: float(np.max(r["h"]) - np.min(r["h"]))),
    ("max(final(h) - 1, 0.0)", HOPPER_FLIGHTS, ["0x1.0600d1b498efap+2", "0x1.e511fef4ed5f2p+2"],
     lambda r: max(r.final["h"] - 1, 0.0)),
    ("min(final(h), final(v), -3)", HOPPER_FLIGHTS,
     ["-0x1.f2b06fa8f0625p+1", "-0x1.8000000000000p+1"],
     lambda r: min(r.final["h"], r.final["v"], -3.0)),
    ("final(u1)", HOPPER_FLIGHTS, ["0x1.820802387c0bep+0", "0x1.7cf0e41514a98p-3"],
     lambda r: float(r["ctrl.u[1]"][-1])),
    ("integral(u1)", HOPPER_FLIGHTS, ["0x1.15ef1f2127943p-3", "-0x1.7a4b17f19237dp-1"], None),
    ("max(u1)", HOPPER_FLIGHTS, ["0x1.820802387c0bep+0", "0x1.7cf0e41514a98p-3"], None),
    ("sqrt(abs(final(v)))", HOPPER_FLIGHTS, ["0x1.f94cff88a8715p+0", "0x1.840e47b88fbb1p+0"],
     lambda r: math.sqrt(abs(r.final["v"]))),
    ("exp(-final(h))", HOPPER_FLIGHTS, ["0x1.920a94861d9a4p-8", "0x1.8a341c0b60e29p-13"],
     lambda r: math.exp(-r.final["h"])),
    ("log(final(m))", HOPPER_FLIGHTS, ["0x1.2618831e495a8p+2", "0x1.266954212e6f3p+2"],
     lambda r: math.log(r.final["m"])),
    ("tanh(final(v)) + sin(initial(h)) * cos(pi)", HOPPER_FLIGHTS,
     ["-0x1.d213adc5d5f4ap-2", "-0x1.be7387e1aa8c0p-2"],
     lambda r: math.tanh(r.final["v"]) + math.sin(float(r["h"][0])) * math.cos(math.pi)),
    ("1 if stopped else 0", HOPPER_FLIGHTS, ["0x1.0000000000000p+0", "0x0.0p+0"], None),
    ("tf", HOPPER_FLIGHTS, ["0x1.4000000000000p+1", "0x1.4cccccccccccdp+0"], None),
    ("final(h) < 3 < 4", HOPPER_FLIGHTS, ["0x0.0p+0", "0x0.0p+0"], None),
    ("10**10**10", HOPPER_FLIGHTS, ["nan", "nan"], None),
    ("log(0*final(h))", HOPPER_FLIGHTS, ["nan", "nan"], None),
    ("abs(final(v)) + 10 * abs(final(h))", HOPPER_FLIGHTS,
     ["0x1.b6ac0d1c4e31ap+5", "0x1.605c2c81e1db5p+6"],
     lambda r: abs(r.final["v"]) + 10 * abs(r.final["h"])),
    ("mean(m) / tf + final(v) ** 2 - -initial(v)", HOPPER_FLIGHTS,
     ["0x1.ba48ce0fbe5c5p+5", "0x1.4940ff9161243p+6"], None),
]


@pytest.mark.parametrize("source,flights,before,oracle", BEFORE, ids=[b[0] for b in BEFORE])
def test_existing_expressions_bit_for_bit(source, flights, before, oracle):
    names = SIGNALS | {"L", "load_max", "y1", "y2"}
    got = [value(source, r, names) for r in flights]
    assert [g.hex() for g in got] == before
    if oracle is not None:
        assert [float(oracle(r)).hex() for r in flights] == before


def test_the_files_objectives_are_the_pinned_ones(hopper_dir, fmu_dir, tmp_path):
    # the expressions pinned above are the tutorial's and reentry.toml's objectives; the
    # tutorial's fuel now reads the plant's output fuel = m0 - m: final(fuel) is what the pinned
    # initial(m) - final(m) computed, bit for bit, on the plant's own flights (oracle: the
    # problem with the pinned expression, which records m, flown through the pythonfmu FMU)
    from descent_fmus.synthesis.run.evaluation import Evaluator
    hop = tomllib.loads((TUTORIAL / "hopper.toml").read_text())["objectives"]
    ree = tomllib.loads(REENTRY.read_text())["objectives"]
    assert [o["flight"] for o in hop] == [BEFORE[0][0], "final(fuel)"]
    assert [o["flight"] for o in ree] == [BEFORE[2][0], BEFORE[3][0]]
    now = load_problem_file(hopper_dir / "hopper.toml", fmu_dir=fmu_dir)
    then = load_problem_file(_hopper_with(hopper_dir, tmp_path, BEFORE[0][0], BEFORE[1][0]),
                             fmu_dir=fmu_dir)
    assert now.record == () and (then.record, then.initial) == ((), ("m",))
    laws = [now.basic(), now.basic().with_q([-12.0, -3.9, 0.32])]
    with Evaluator(now, fmu_dir) as a, Evaluator(then, fmu_dir) as b:
        Fa, Fb = a.evaluate(laws).F, b.evaluate(laws).F
    assert Fa.tobytes() == Fb.tobytes() and (Fa[:, 1] > 0.5).all()


# -- pickling ----------------------------------------------------------------------------------
def test_expressions_pickle():
    r = hopper_flight()
    for source in ("integral(h**2 + 0.1*u1**2)", "max(sqrt(h**2 + v**2)) + final(abs(v))",
                   "mean(v if v > 0 else 0) - min(final(h), 0)",
                   "abs(final(m) - 99) if final(v) < 0 else max(final(h) - 1, 0)"):
        fe = FlightExpression(Expression(source, SIGNALS), LAW, True, 3.0)
        copy = pickle.loads(pickle.dumps(fe))
        assert copy.expression.terms == fe.expression.terms
        assert copy.expression.reductions == fe.expression.reductions
        assert copy(r).hex() == fe(r).hex()


# -- problem files: checking, recording and a flight through the FMUs --------------------------
def _hopper_with(hopper_dir, tmp_path, *flights):
    """The tutorial file with its objectives' expressions replaced by ``flights``."""
    text = (hopper_dir / "hopper.toml").read_text()
    for old, new in zip(('"abs(final(v))"', '"final(fuel)"'), flights):
        assert old in text
        text = text.replace(old, f'"{new}"', 1)
    shutil.copy(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu")
    path = tmp_path / "p.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("flights,record,initial", [
    (("abs(final(v))", "final(fuel)"), (), ()),                           # the tutorial as is
    # values at t = 0 only: read there, no recording where the loop can (the C master)
    (("abs(final(v))", "initial(m) - final(m)"), (), ("m",)),
    (("initial(h) + final(h)", "initial(m) - final(m)"), (), ("h", "m")),
    # ... unless something else records: then they are recorded too
    (("max(h)", "initial(m) - final(m)"), ("h", "m"), ()),
    (("final(u1)", "initial(m)"), ("m", "ctrl.u[1]"), ()),
    (("final(abs(v) + 10*h)", "final(m)"), (), ()),                       # finals: no recording
    (("integral(h**2 + 0.1*u1**2)", "final(m)"), ("h", "ctrl.u[1]"), ()),
    (("max(sqrt(h**2 + v**2))", "mean(v if v > 0 else 0)"), ("h", "v"), ()),
    (("final(u1)", "final(h)"), ("ctrl.u[1]",), ()),                      # a law output
])
def test_the_problem_records_what_its_reductions_need(hopper_dir, fmu_dir, tmp_path, flights,
                                                      record, initial):
    problem = load_problem_file(_hopper_with(hopper_dir, tmp_path, *flights), fmu_dir=fmu_dir)
    assert (problem.record, problem.initial) == (record, initial)


def test_reentry_file_records_nothing(fmu_dir):
    assert load_problem_file(REENTRY, fmu_dir=fmu_dir).record == ()


@pytest.mark.parametrize("flight,words", [
    ("max(integral(h))", ["objectives[1].flight", "integral() inside max()"]),
    ("integral(h) + v", ["objectives[1].flight", "signal 'v' must be reduced"]),
    ("max(hh)", ["objectives[1].flight", "unknown signal 'hh'"]),
    ("abs(final(v), 1)", ["objectives[1].flight", "abs() takes one argument"]),
])
def test_file_errors_name_the_key(hopper_dir, fmu_dir, tmp_path, flight, words):
    with pytest.raises(ProblemFileError) as exc:
        load_problem_file(_hopper_with(hopper_dir, tmp_path, flight), fmu_dir=fmu_dir)
    msg = str(exc.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_non_real_signals_only_inside_final(fmu_dir, tmp_path):
    text = REENTRY.read_text()
    old = 'flight = "final(load_max)"'
    for new, ok in (("final(load_max * (status == 1))", True), ("max(load_max + status)", False),
                    ("initial(status)", False)):
        path = tmp_path / "r.toml"
        path.write_text(text.replace(old, f'flight = "{new}"', 1))   # Reentry.fmu: fmu_dir
        if ok:
            assert load_problem_file(path, fmu_dir=fmu_dir).record == ()
        else:
            with pytest.raises(ProblemFileError) as exc:
                load_problem_file(path, fmu_dir=fmu_dir)
            assert "objectives[1].flight" in str(exc.value)
            assert "'status' is Integer" in str(exc.value) and "final()" in str(exc.value)


def test_quadratic_cost_through_the_fmus(hopper_dir, fmu_dir, tmp_path):
    # Oracle: the same law flown by a ClosedLoop recording h and u[1]; the integral computed
    # here from the recorded arrays by the trapezoidal rule
    from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
    from descent_fmus.synthesis.run.evaluation import Evaluator
    path = _hopper_with(hopper_dir, tmp_path, "integral(h**2 + 0.1*u1**2)", "max(abs(v))")
    problem = load_problem_file(path, fmu_dir=fmu_dir)
    law = problem.basic()
    with Evaluator(problem, fmu_dir) as ev:
        F = ev.evaluate([law]).F[0]
    plant, ctrl = problem.fmu_paths(fmu_dir)
    costs, peaks = [], []
    with ClosedLoop(problem.wiring, plant, ctrl, record=["h", "v"]) as loop:
        for s in problem.initial_states:
            r = loop.run(plant_values=s, controller_values=law.start_values(), record=True)
            y = r["h"] ** 2 + 0.1 * r["ctrl.u[1]"] ** 2
            # + the file's unmet_stop_penalty (100) for a flight that never touched down
            costs.append(0.5 * np.sum((y[1:] + y[:-1]) * np.diff(r.time))
                         + (0.0 if r.stopped else 100.0))
            peaks.append(np.max(np.abs(r["v"])))
            assert len(r.time) > 10
    # the tutorial's objectives aggregate by max (v_touchdown) and mean (fuel)
    assert F[0] == pytest.approx(max(costs), rel=1e-12)
    assert F[1] == pytest.approx(np.mean(peaks), rel=1e-12)
    assert F[0] > 0.0
