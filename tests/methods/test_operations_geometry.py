"""Operations of geometry and switching: binary ``atan2`` and ``hypot``, unary ``wrap`` and
the signed square ``ssq`` (z|z|).

Oracles: the Python evaluation of the one operation table
(``models/controllers/operation_table.py``) for the native matrix interpreter (the native
``NetworkOperatorController`` FMU, ``c/no_interp.c``) and for the exported C law (``law.c``,
compiled here) --
bitwise (``struct.pack('<d')``), on random inputs and on extremes (+-0, +-1e8, tiny and
subnormal numbers, both sides of atan2's branch cut, NaN and infinities); the closed forms
``math.hypot``, ``numpy.arctan2``, ``math.copysign(z * z, z)`` and the wrapped angle for a
small law (tolerances stated at each assertion); atan2's fold as docs/methods/network_operator.md defines it (first arc sets the
node, later arcs fold ``a <- atan2(a, b)``); the operation table's names for the problem-file and
command-line choices (one-line errors listing the valid names).
"""
from __future__ import annotations

import ctypes
import math
import shutil
import struct
import subprocess
import sys

import numpy as np
import pytest

from descent_fmus.models.controllers.law_interpreter import compile_law, evaluate
from descent_fmus.models.controllers.operation_table import (BINARY, BINARY_OPS, BIG, UNARY,
                                                             UNARY_OPS, OperationNameError,
                                                             operation_numbers)
from descent_fmus.synthesis.fmi.slave import load_slave
from descent_fmus.synthesis.fmi.native.builders.build import COMPILE_FLAGS, find_compiler
from descent_fmus.synthesis.fmi.native.builders.ccode import law_c, operations_c
from descent_fmus.synthesis.fmi.native.builders.controllers import (
    build_network_operator_controller)
from descent_fmus.synthesis.methods.law import NetworkOperator

from fmi_calls import start

ATAN2, HYPOT = operation_numbers(["atan2", "hypot"], binary=True)
WRAP, SSQ = operation_numbers(["wrap", "ssq"])
SSQRT, = operation_numbers(["ssqrt"])
ID, NEG = operation_numbers(["id", "neg"])
PI = math.pi
#: operands: zeros of both signs, subnormal and tiny numbers, the clamp, angles at and beside
#: the multiples of pi (wrap's cut), and the largest arc values the unary operations give
SPECIAL = [0.0, -0.0, 5e-324, -5e-324, 1e-300, -1e-300, 1e-8, -1e-8, 0.5, 1.0, -1.0, PI, -PI,
           math.nextafter(PI, 4.0), math.nextafter(PI, 0.0), math.nextafter(-PI, -4.0),
           math.nextafter(-PI, 0.0), 2 * PI, -2 * PI, 3 * PI, -3 * PI, 7.5, -1e3, 1e8, -1e8,
           math.nextafter(1e8, 0.0), 1e16, -1e24]
#: law inputs besides the random ones: the above, the clamp's far side, NaN, infinities
EXTREMES = SPECIAL + [1e300, -1e300, math.inf, -math.inf, math.nan, 1.7976931348623157e308]

cc = find_compiler()
needs_cc = pytest.mark.skipif(cc is None, reason="no C compiler (CI installs gcc)")
#: the native build's flags, every symbol visible (ctypes calls the functions), no warning
FLAGS = [f for f in COMPILE_FLAGS if not f.startswith("-fvisibility")] + ["-Werror"]


def bits(v: float) -> bytes:
    return struct.pack("<d", v)


def _compile(d, sources: dict, main: list):
    for name, text in sources.items():
        (d / name).write_text(text)
    lib = d / "lib.so"
    subprocess.run([cc, *FLAGS, "-shared", "-I", str(d), *[str(d / m) for m in main], "-o",
                    str(lib), "-lm"], check=True)
    return ctypes.CDLL(str(lib))


def test_the_table_grows_at_its_end():
    # the numbers of pinned laws and Pareto sets do not move: the 28 unary and 8 binary
    # operations of the reentry paper and its wider set keep their numbers
    assert [op.name for op in UNARY_OPS[1:29]][:5] == ["id", "sq", "neg", "ssqrt", "inv"]
    assert UNARY_OPS[28].name == "gauss" and BINARY_OPS[8].name == "smax"
    assert (WRAP, ATAN2, HYPOT, SSQ) == (29, 9, 10, 30)
    assert [op.number for op in UNARY_OPS[1:]] == list(range(1, len(UNARY)))
    assert [op.number for op in BINARY_OPS[1:]] == list(range(1, len(BINARY)))


def test_operations_equal_their_closed_forms():
    # wrap: the angle in (-pi, pi] congruent to z modulo 2 pi (float 2 pi): |difference| a
    # multiple of 2 pi to 1e-15 relative; atan2 after the first arc: numpy.arctan2 to 1 ulp
    # with its sign (zeros too); hypot sqrt(a^2 + b^2): math.hypot (correctly rounded) to 2 ulp
    for z in SPECIAL + list(np.random.default_rng(1).uniform(-50, 50, 500)):
        w = UNARY[WRAP](z)
        assert -PI < w <= PI, z
        k = (z - w) / (2 * PI)
        assert abs(k - round(k)) <= 1e-15 * max(1.0, abs(k)), (z, w)
    assert UNARY[WRAP](-PI) == PI == UNARY[WRAP](PI) and UNARY[WRAP](2 * PI) == 0.0
    assert bits(UNARY[WRAP](-0.0)) == bits(-0.0)
    for a in SPECIAL[:-2]:
        for b in SPECIAL:
            t, want = BINARY[ATAN2](a, b), float(np.arctan2(a, b))
            assert abs(t - want) <= math.ulp(want) and math.copysign(1.0, t) == \
                math.copysign(1.0, want), (a, b, t, want)
            assert bits(BINARY[ATAN2](math.nan, b)) == bits(b)      # the first arc sets it
            # 2 ulp (two rounded squares, a rounded sum and sqrt); where the squares
            # underflow (both operands below 1e-150) 1e-150 absolute: a law cannot tell it
            # from 0 ([choice] in docs/methods/network_operator.md)
            h, want = BINARY[HYPOT](a, b), math.hypot(a, b)
            assert abs(h - want) <= (2 * math.ulp(want) if want > 1e-150 else 1e-150), (a, b)
    # the branch cut: atan2(+-0, negative) = +-pi, atan2(+-tiny, negative) -> +-pi
    assert BINARY[ATAN2](0.0, -1.0) == PI and BINARY[ATAN2](-0.0, -1.0) == -PI
    assert BINARY[ATAN2](-5e-324, -1.0) == -PI and BINARY[ATAN2](5e-324, -1.0) == PI


def test_the_signed_square_is_odd_and_inverts_ssqrt():
    # ssq(z) = z|z| = copysign(z^2, z), exactly (one rounding either way), with the sign of
    # zero kept; the inverse of ssqrt to 2 ulp on 20 decades (ssqrt rounds once, the square
    # doubles its relative error); odd: ssq(-z) = -ssq(z) bitwise
    zs = SPECIAL + list(np.random.default_rng(3).normal(0, 1, 2000) * 10.0 ** np.random.
                        default_rng(4).uniform(-10, 10, 2000))
    for z in zs:
        assert bits(UNARY[SSQ](z)) == bits(math.copysign(z * z, z)), z
        assert bits(UNARY[SSQ](-z)) == bits(-UNARY[SSQ](z)), z
        if 1e-150 < abs(z) < 1e150:
            back = UNARY[SSQ](UNARY[SSQRT](z))
            assert abs(back - z) <= 2 * math.ulp(z), (z, back)
    assert bits(UNARY[SSQ](-0.0)) == bits(-0.0) and UNARY[SSQ](-3.0) == -9.0


@needs_cc
def test_c_operations_equal_python_bitwise(tmp_path):
    # the three operations rendered to C (the native build's flags) on every pair of the
    # special operands and 4000 random ones over 30 decades: the same doubles as Python; the
    # node value a of atan2 is NaN (no arc yet) or clamped
    src = "#include <math.h>\n" + operations_c([WRAP, SSQ], [ATAN2, HYPOT], helpers=())
    src += (f"double w(double z) {{ return rho{WRAP}(z); }}\n"
            f"double s(double z) {{ return rho{SSQ}(z); }}\n"
            f"double t(double a, double b) {{ return chi{ATAN2}(a, b); }}\n"
            f"double h(double a, double b) {{ return chi{HYPOT}(a, b); }}\n")
    lib = _compile(tmp_path, {"ops.c": src}, ["ops.c"])
    for f in ("w", "s", "t", "h"):
        getattr(lib, f).restype = ctypes.c_double
        getattr(lib, f).argtypes = [ctypes.c_double] * (1 if f in "ws" else 2)
    rng = np.random.default_rng(5)
    vals = SPECIAL + [-v for v in SPECIAL] + [float(v) for v in np.exp(
        rng.uniform(-35, 35, 4000)) * rng.choice([-1, 1], 4000)]
    for z in vals:
        assert bits(lib.w(z)) == bits(UNARY[WRAP](z)), z
    # ssq's operand is any arc's source (an input: NaN, infinities, overflow to inf)
    for z in vals + [math.inf, -math.inf, 1e300, -1.7976931348623157e308, math.nan]:
        assert bits(lib.s(z)) == bits(UNARY[SSQ](z)) or (z != z and lib.s(z) != lib.s(z)), z
    pairs = [(a, b) for a in SPECIAL + [math.nan] for b in SPECIAL] + list(zip(vals, vals[::-1]))
    n = 0
    for a, b in pairs:
        if a != a or abs(a) <= BIG:
            assert bits(lib.t(a, b)) == bits(BINARY[ATAN2](a, b)), (a, b)
            assert bits(lib.h(a, b)) == bits(BINARY[HYPOT](a, b)), (a, b)
            n += 1
    assert n > 2000


def polar_law() -> NetworkOperator:
    """The unicycle's polar coordinates from x, y, theta: rho = hypot(x, y), phi = atan2(-y,
    -x), alpha = wrap(phi - theta).  Nodes: 1 x, 2 y, 3 theta, 4 = -x, 5 = atan2(-y, z4),
    6 = hypot(x, y), 7 = z5 - theta, 8 = wrap(z7)."""
    psi = np.zeros((8, 8), dtype=int)
    for j in range(3, 8):
        psi[j, j] = 1                                   # add
    psi[4, 4], psi[5, 5] = ATAN2, HYPOT
    psi[0, 3] = NEG
    psi[1, 4], psi[3, 4] = NEG, ID                      # the first arc (from node 2) sets node 5
    psi[0, 5], psi[1, 5] = ID, ID
    psi[2, 6], psi[4, 6] = NEG, ID
    psi[6, 7] = WRAP
    return NetworkOperator(psi, nx=3, q=[], outputs=[6, 5, 8], bounds=[(-1e9, 1e9)] * 3,
                           input_names=["x", "y", "theta"])


def test_a_polar_law_computes_its_closed_form():
    # 2000 random poses: rho to 1 ulp of math.hypot, phi to 1 ulp of numpy.arctan2(-y, -x),
    # alpha = phi - theta wrapped into (-pi, pi] to 1e-15 absolute (away from
    # the cut by 1e-9)
    law = polar_law()
    rng = np.random.default_rng(2)
    for x, y, th in zip(rng.normal(0, 3, 2000), rng.normal(0, 3, 2000),
                        rng.uniform(-PI, PI, 2000)):
        rho, phi, alpha = law.raw([x, y, th])
        assert abs(rho - math.hypot(x, y)) <= math.ulp(math.hypot(x, y))
        assert abs(phi - float(np.arctan2(-y, -x))) <= 4.5e-16      # 1 ulp at pi
        want = phi - th + (2 * PI if phi - th <= -PI else -2 * PI if phi - th > PI else 0.0)
        if abs(abs(phi - th) - PI) > 1e-9:
            assert abs(alpha - want) <= 1e-15, (x, y, th, alpha, want)
    # the origin and the branch cut: phi(0, 0) = atan2(-0, 0 + -0) = atan2(-0, +0) = -0 (the
    # add node's unit +0 absorbs -0); phi(1, -+0) = +-pi
    assert [bits(v) for v in law.raw([0.0, 0.0, 0.0])[:2]] == [bits(0.0), bits(-0.0)]
    assert law.raw([1.0, -0.0, 0.0])[1] == PI and law.raw([1.0, 0.0, 0.0])[1] == -PI


def test_atan2_folds_its_arcs_in_evaluation_order():
    # nodes 1..3 inputs; node 4 atan2 with k = 0..3 incoming arcs (id): 0 arcs -> 0 (finite of
    # "no value"), 1 -> b1, 2 -> atan2(b1, b2), 3 -> atan2(atan2(b1, b2), b3)
    b = [0.3, -2.0, 5.0]
    for k, want in enumerate([0.0, b[0], math.atan2(b[0], b[1]),
                              math.atan2(math.atan2(b[0], b[1]), b[2])]):
        psi = [[0] * 4 for _ in range(4)]
        psi[3][3] = ATAN2
        for i in range(k):
            psi[i][3] = ID
        assert evaluate(compile_law(psi, 3, 0, [4]), b) == [want], k


def random_geometry_law(rng, L: int = 14, nx: int = 3) -> NetworkOperator:
    """A random law rich in the new operations: half the nodes atan2 or hypot, a third of the
    arcs wrap or ssq, some nodes without incoming arcs; two outputs, a parameter."""
    psi = np.zeros((L, L), dtype=int)
    ns = nx + 1
    for j in range(ns, L):
        psi[j, j] = rng.choice([ATAN2, HYPOT, ATAN2, HYPOT, 1, 2, 3, 6])
        for i in range(j):
            if rng.random() < 0.3:
                psi[i, j] = rng.choice([WRAP, SSQ, ID, NEG, 2, 5, 7, 12, 14, 20])
    return NetworkOperator(psi, nx=nx, q=[float(rng.normal(0, 2))], outputs=[L, L - 1],
                           bounds=[(-1e9, 1e9)] * 2)


@pytest.fixture
def interpreter(fmu_dir, tmp_path):
    """The native NetworkOperatorController (the matrix interpreter c/no_interp.c with the
    generated operation table), as build_fmus.py built it, else built here."""
    path = fmu_dir / "native" / "NetworkOperatorController.fmu"
    if not path.is_file():
        path = build_network_operator_controller(tmp_path / "NetworkOperatorController.fmu")
    fmu = load_slave(path, "interpreter")
    yield fmu
    fmu.freeInstance()


def _laws_as_c(d, laws):
    """The exported C of every law (``law_c``, prefix ``l<k>``) compiled into one library."""
    sources, main = {}, []
    for k, law in enumerate(laws):
        h, c = law_c(law, prefix=f"l{k}", header=f"l{k}.h")
        sources[f"l{k}.h"], sources[f"l{k}.c"] = h, c
        main.append(f"l{k}.c")
    return _compile(d, sources, main)


@needs_cc
def test_python_interpreter_and_exported_c_agree_bitwise(interpreter, tmp_path):
    # the polar law and 8 random laws rich in atan2/hypot/wrap/ssq, 200 random inputs each over
    # 1e-3..1e6 plus 400 drawn from the extremes (incl. NaN, +-inf, +-0, both sides of the cut)
    # and the cut itself (y = +-0, +-5e-324 with x < 0): Python = the native interpreter FMU
    # (the law loaded as start values) = law.c, bitwise
    rng = np.random.default_rng(37)
    laws = [polar_law()] + [random_geometry_law(rng) for _ in range(8)]
    # the sample holds atan2 nodes with 0, 1 and more incoming arcs, hypot nodes with 1 and more
    kinds = {(int(law.psi[j, j]), min(2, int(np.count_nonzero(law.psi[:j, j]))))
             for law in laws for j in range(law.nx + len(law.q), law.size)}
    assert {(ATAN2, 0), (ATAN2, 1), (ATAN2, 2), (HYPOT, 1), (HYPOT, 2)} <= kinds
    assert sum(int(np.sum(law.psi == SSQ)) for law in laws) >= 10       # ssq arcs, too
    exported = _laws_as_c(tmp_path, laws)
    D = ctypes.c_double
    n = 0
    for k, law in enumerate(laws):
        nu = len(law.outputs)
        vr = start(interpreter, law.start_values())       # the law as start values alone
        xi = [vr[f"x[{i + 1}]"] for i in range(law.nx)]
        ui = [vr[f"u[{i + 1}]"] for i in range(nu)]
        f = getattr(exported, f"l{k}")
        xs = [list(v) for v in rng.normal(0, 1, (200, law.nx)) * rng.choice(
            [1e-3, 1.0, 30.0, 1e6], (200, 1))]
        xs += [[float(v) for v in rng.choice(EXTREMES, law.nx)] for _ in range(400)]
        xs += [[x, y] + [0.5] * (law.nx - 2) for x in (-1.0, -1e8, -5e-324)
               for y in (0.0, -0.0, 5e-324, -5e-324)]
        for x in xs:
            want, u = law.raw(x), (D * nu)()
            interpreter.setReal(xi, x)
            f((D * law.nx)(*x), u)
            assert [bits(v) for v in interpreter.getReal(ui)] == [bits(v) for v in want], (k, x)
            assert [bits(v) for v in u] == [bits(v) for v in want], (k, x, list(u), want)
            assert all(math.isfinite(v) for v in want)
            n += 1
    assert n > 5_000


def test_readable_formulas_print_them():
    # the named atan2, hypot and wrap, in text and LaTeX; the readable form evaluates
    # to the matrix law within 1e-12 (its oracle) away from wrap's cut
    law = polar_law()
    r = law.readable()
    assert r.text == "t1 = atan2(-y, -x); u1 = clip(hypot(x, y), -1e+09, 1e+09); u2 = clip(" \
        "t1, -1e+09, 1e+09); u3 = clip(wrap(t1 - theta), -1e+09, 1e+09)", r.text
    assert r"\operatorname{hypot}" in r.latex and r"\operatorname{wrap}" in r.latex
    assert r"\operatorname{atan2}\left(- y, - x\right)" in r.latex, r.latex
    assert set(r.functions) == {"atan2", "hypot", "wrap"}
    assert "atan2(-(y), -(x))" in law.formula() and "hypot(x, y)" in law.formula()
    rng = np.random.default_rng(4)
    for x in rng.normal(0, 2, (200, 3)):
        for a, b in zip(r.evaluate(list(x)), law.raw(list(x))):
            assert abs(a - b) <= 1e-12 * max(1.0, abs(b))
    # a hypot node with one arc is |b|, printed as such
    psi = np.zeros((3, 3), dtype=int)
    psi[2, 2], psi[0, 2] = HYPOT, NEG
    one = NetworkOperator(psi, nx=1, q=[1.0], outputs=[3], bounds=[(-5.0, 5.0)])
    assert one.readable().text == "u = clip(Abs(x1), -5, 5)" and one.raw([-2.0]) == [2.0]


def test_operation_names_and_numbers():
    assert operation_numbers(["id", 3, "29", " wrap"]) == (1, 3, 29, 29)
    assert operation_numbers("atan2,hypot".split(","), binary=True) == (9, 10)
    with pytest.raises(OperationNameError) as exc:
        operation_numbers(["add", "atan3"], binary=True)
    msg = str(exc.value)
    assert msg.startswith("unknown binary operation 'atan3'; valid: 1 add, 2 mul") \
        and "9 atan2, 10 hypot" in msg and "\n" not in msg
    for bad in ([0], [31], [True], [1.0], ["max"]):        # max is binary, not unary
        with pytest.raises(OperationNameError, match="unknown unary operation"):
            operation_numbers(bad)


def test_problem_files_and_the_command_line_choose_the_operations(hopper_dir, fmu_dir,
                                                                  tmp_path):
    # [ga] unary/binary by name or number reach the problem (and so the variations); a bad
    # name is a one-line error naming the key and listing the valid names; --unary/--binary
    # override the file, a bad one exits 2 with one line before anything is written
    from descent_fmus.synthesis.problems.files import ProblemFileError, load_problem_file
    shutil.copy(hopper_dir / "Hopper.fmu", tmp_path / "Hopper.fmu")
    text = (hopper_dir / "hopper.toml").read_text()
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[ga]", '[ga]\nunary = ["id", "neg", "wrap", 14]\n'
                                         'binary = ["add", 2, "atan2", "hypot"]', 1))
    problem = load_problem_file(good, fmu_dir=fmu_dir)
    assert (problem.unary, problem.binary) == ((1, 3, 29, 14), (1, 2, 9, 10))
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[ga]", '[ga]\nbinary = ["add", "atan"]', 1))
    with pytest.raises(ProblemFileError) as exc:
        load_problem_file(bad, fmu_dir=fmu_dir)
    msg = str(exc.value)
    assert "ga.binary: unknown binary operation 'atan'; valid: 1 add" in msg and "\n" not in msg

    from descent_fmus.synthesis.cli.main import build_parser
    from descent_fmus.synthesis.cli.synthesize import apply_options
    args = build_parser().parse_args(["synthesize", "--problem", str(good), "--unary",
                                      "sin,cos,wrap", "--binary", "hypot"])
    p = apply_options(problem, args)
    assert (p.unary, p.binary) == ((12, 11, 29), (10,))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "descent_fmus.synthesis.cli.main", "synthesize",
                        "--problem", str(good), "--binary", "add,hypt", "--out", str(out),
                        "--fmus", str(fmu_dir)], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "--binary: unknown binary operation 'hypt'; valid: 1 add" in r.stderr, r.stderr
    assert not out.exists()


def test_readable_formulas_print_the_signed_square():
    # ssq enters readable laws through SymPy (z*Abs(z)): the linear law with x2's product arc
    # through ssq, u = -2 x1 + ssq(-3 x2) = -2 x1 - 9 x2|x2| (the closed form, by hand);
    # the readable form evaluates to the matrix law within 1e-12 (its oracle)
    lin = NetworkOperator.linear([[-2.0, -3.0]], [0.0], bounds=[(-1.0, 1.0)], size=8)
    psi = lin.psi.copy()
    psi[6, 7] = SSQ                                      # the arc x2 * q2 -> the sum node
    law = NetworkOperator(psi, nx=2, q=lin.q, outputs=lin.outputs, bounds=lin.bounds)
    r = law.readable()
    assert r.text == "u = clip(-2*x1 - 9*x2*Abs(x2), -1, 1)", r.text
    assert r"x_{2} \left|{x_{2}}\right|" in r.latex, r.latex
    assert "ssq((x2*-3))" in law.formula()
    for x in np.random.default_rng(6).normal(0, 2, (200, 2)):
        want = -2.0 * x[0] - 9.0 * x[1] * abs(x[1])
        assert abs(law.raw(list(x))[0] - want) <= 1e-12 * max(1.0, abs(want))
        assert abs(r.evaluate(list(x))[0] - want) <= 1e-12 * max(1.0, abs(want))
