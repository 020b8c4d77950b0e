"""Synthesis problems from a TOML file, for any FMI 2.0 co-simulation plant FMU.

``descent-fmus synthesize --problem FILE.toml --out DIR`` runs the network-operator synthesis on
a plant this package knows nothing about: the file names the plant FMU (any tool's), which of its
outputs feed the law and which of its inputs the law drives, the sampling period, when a flight
ends, the initial states, the objectives and the basic law.  The format, key by key::

    [problem]
    name = "hopper"                      # letters, digits, - and _
    description = "..."                  # optional

    [plant]
    fmu = "Hopper.fmu"                   # relative to this file, else to the FMU folder
    parameters = { g = 1.62 }            # optional: start values of every flight

    [controller]                          # the generic NetworkOperatorController FMU
    inputs = [ { output = "h", scale = 0.01 },        # x[1] = scale * (h - offset)
               { output = "v", scale = 0.1, offset = 0.0 } ]
    outputs = [ { input = "thrust", min = 0.0, max = 2.0 } ]   # u[1] drives 'thrust'
    # fmu = "NetworkOperatorController.fmu"            # default: the package's, FMU folder

    [simulation]
    step = 0.1                            # communication step = the law's sample period [s]
    stop_time = 20.0                      # [s]
    stop = { output = "h", op = "<=", value = 0.0 }    # optional; op is "<=", ">=" or "!="

    [initial_states]                      # either a list ...
    states = [ { h0 = 10.0, v0 = 0.0 }, { h0 = 12.0, v0 = -1.0 } ]
    # ... or a box and a seeded sampler (uniform, lhs, corners)
    # box = { h0 = [8.0, 12.0], v0 = [-1.0, 1.0] }
    # samples = 8
    # sampler = "lhs"
    # seed = 1

    [[objectives]]                        # one table per objective (all minimised)
    name = "miss"
    flight = "abs(final(v)) + 10 * abs(final(h))"      # per flight (synthesis.problems.expressions)
    over_states = "sum"                   # sum | mean | max over the initial states
    unmet_stop_penalty = 100.0            # added for a flight the stop condition never ended
    penalty = 1e6                         # a law whose evaluation fails gets this

    [basic_law]                           # the GA's first basic solution: a linear law ...
    gains = [ [ -1.0, -2.0 ] ]            # one row per output: u_k = sum_i gains[k][i] x_i + bias[k]
    bias = [ 1.0 ]
    size = 16                             # nodes (room for the GA's structure)
    # ... or a law file of a previous synthesis:   file = "law.json"
    # ... or a matrix inline:  psi = [[...]], q = [...], outputs = [...]

    [ga]                                  # optional: the default budget
    population = 64
    generations = 40
    crossovers = 16
    lchr = 6
    epoch = 8
    seed = 1
    q_range = [-16.0, 16.0]               # range of the parameters' Gray code
    q_bits = [4, 12]                      # its integer and fraction bits (default 4 + 12)
    # unary = [1, 3, 4, 5, 8, 9, 10, 14, 15]   binary = [1, 2]   (operation numbers)

Every error names the file, the key and the problem (:class:`ProblemFileError`); nothing is
written before the file has been checked against the plant FMU's model description.
"""
from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from pathlib import Path

from descent_fmus.synthesis.fmi.closed_loop import Stop, Wiring
from descent_fmus.synthesis.problems.expressions import Expression, ExpressionError, reduce_signal
from descent_fmus.synthesis.problems.contract import PAPER_BINARY, PAPER_UNARY, Budget, SynthesisProblem

try:
    import tomllib
except ModuleNotFoundError:              # Python 3.10
    import tomli as tomllib

__all__ = ["ProblemFileError", "load_problem_file", "FileObjectives"]

_TOP = {"problem", "plant", "controller", "simulation", "initial_states", "objectives",
        "basic_law", "ga"}
_KEYS = {
    "problem": {"name", "description"},
    "plant": {"fmu", "parameters"},
    "controller": {"fmu", "inputs", "outputs"},
    "controller.inputs": {"output", "scale", "offset"},
    "controller.outputs": {"input", "min", "max"},
    "simulation": {"step", "stop_time", "stop"},
    "simulation.stop": {"output", "op", "value"},
    "initial_states": {"states", "box", "samples", "sampler", "seed"},
    "objectives": {"name", "flight", "over_states", "unmet_stop_penalty", "penalty"},
    "basic_law": {"gains", "bias", "size", "file", "psi", "q", "outputs"},
    "ga": {"population", "generations", "crossovers", "lchr", "epoch", "seed", "q_range",
           "q_bits", "unary", "binary"},
}
_OVER = ("sum", "mean", "max")


class ProblemFileError(ValueError):
    """A problem file is malformed; the message names the file, the key and the problem."""


@dataclass(frozen=True)
class _Objective:
    name: str
    expression: Expression
    over: str
    unmet_stop_penalty: float


@dataclass(frozen=True)
class FileObjectives:
    """The objective function of a problem file (picklable: sent to the worker processes).

    Per flight, every objective's expression is evaluated on the reductions of the recorded
    signals (``final`` from the plant's final outputs); the values are aggregated over the
    initial states (sum, mean or max).
    """

    objectives: tuple
    law_outputs: tuple       # (signal name "u1", controller output "u[1]") pairs
    has_stop: bool

    def __call__(self, results):
        per_flight = [self._flight(r) for r in results]
        f = []
        for j, ob in enumerate(self.objectives):
            vals = [v[j] for v in per_flight]
            if ob.over == "sum":
                f.append(sum(vals))
            elif ob.over == "mean":
                f.append(sum(vals) / len(vals))
            else:
                f.append(max(vals))
        return tuple(f), {"stopped": sum(bool(r.stopped) for r in results)}

    def _flight(self, r) -> list:
        law = dict(self.law_outputs)
        values = {}
        for ob in self.objectives:
            for fn, name in ob.expression.reductions:
                if (fn, name) in values:
                    continue
                if name in law:
                    x = r.outputs.get("ctrl." + law[name], ())
                    final = float(x[-1]) if len(x) else math.nan
                else:
                    x = r.outputs.get(name, ())
                    final = float(r.final[name])
                values[(fn, name)] = reduce_signal(fn, r.time, x, final)
        special = {"tf": r.t_final, "stopped": 1.0 if r.stopped else 0.0}
        out = []
        for ob in self.objectives:
            v = ob.expression.evaluate(values, special)
            if self.has_stop and not r.stopped and ob.unmet_stop_penalty:
                v += ob.unmet_stop_penalty
            out.append(v)
        return out


class _Reader:
    """Reads one file, raising ProblemFileError(file: key: problem)."""

    def __init__(self, path: Path):
        self.path = path

    def error(self, key: str, message: str):
        return ProblemFileError(f"{self.path}: {key}: {message}")

    def table(self, data, key: str, required: bool = True) -> dict:
        v = data.get(key.split(".")[-1]) if isinstance(data, dict) else None
        if v is None:
            if required:
                raise self.error(key, "missing")
            return {}
        if not isinstance(v, dict):
            raise self.error(key, f"must be a table, got {type(v).__name__}")
        return v

    def items(self, d: dict, key: str, allowed: set):
        """``(key[k], table)`` for every table of the non-empty list ``d[last part of key]``."""
        v = d.get(key.split(".")[-1])
        if not isinstance(v, list) or not v:
            raise self.error(key, "must be a non-empty list of tables")
        for k, item in enumerate(v):
            kk = f"{key}[{k + 1}]"
            if not isinstance(item, dict):
                raise self.error(kk, f"must be a table with keys {', '.join(sorted(allowed))}")
            self.keys(item, kk, allowed)
            yield kk, item

    def keys(self, d: dict, key: str, allowed: set) -> None:
        for k in d:
            if k not in allowed:
                raise self.error(f"{key}.{k}", f"unknown key; allowed: {', '.join(sorted(allowed))}")

    def number(self, d: dict, key: str, name: str, default=None, positive=False,
               integer=False):
        if name not in d:
            if default is None:
                raise self.error(f"{key}.{name}", "missing")
            return default
        v = d[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.error(f"{key}.{name}", f"must be a number, got {v!r}")
        if integer and not isinstance(v, int):
            raise self.error(f"{key}.{name}", f"must be an integer, got {v!r}")
        if not math.isfinite(v):
            raise self.error(f"{key}.{name}", f"must be finite, got {v!r}")
        if positive and v <= 0:
            raise self.error(f"{key}.{name}", f"must be > 0, got {v!r}")
        return v

    def string(self, d: dict, key: str, name: str, default=None) -> str:
        if name not in d:
            if default is None:
                raise self.error(f"{key}.{name}", "missing")
            return default
        v = d[name]
        if not isinstance(v, str) or not v:
            raise self.error(f"{key}.{name}", f"must be a non-empty string, got {v!r}")
        return v


def _fmu(reader: _Reader, key: str, name: str, fmu_dir) -> Path:
    p = Path(name)
    candidates = [p] if p.is_absolute() else [reader.path.parent / p] + (
        [Path(fmu_dir) / p] if fmu_dir is not None else [])
    for c in candidates:
        if c.is_file():
            return c.resolve()
    raise reader.error(key, f"FMU file not found: {name} (looked in "
                            f"{', '.join(str(c.parent) for c in candidates)}; build it first, e.g. "
                            f"python build_fmus.py for the package's FMUs)")


def _model_description(reader: _Reader, key: str, path: Path):
    import zipfile
    from xml.etree import ElementTree as ET

    from fmpy import read_model_description
    try:
        with zipfile.ZipFile(path) as z:
            root = ET.fromstring(z.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError) as exc:
        raise reader.error(key, f"{path} is not a readable FMU: {exc}") from None
    version = root.get("fmiVersion", "?")
    if version != "2.0":
        raise reader.error(key, f"{path.name} is an FMI {version} FMU; descent-fmus needs "
                                f"FMI 2.0")
    if root.find("CoSimulation") is None:
        raise reader.error(key, f"{path.name} is not a co-simulation FMU (model exchange "
                                f"only); export it for co-simulation")
    try:
        return read_model_description(str(path))
    except Exception as exc:  # fmpy's schema validation lists every problem on its own line
        lines = str(exc).splitlines()
        more = f" (+{len(lines) - 2} more)" if len(lines) > 2 else ""
        raise reader.error(key, f"{path.name}: invalid model description: "
                                f"{' '.join(x.strip() for x in lines[:2])}{more}") from None


def load_problem_file(path, fmu_dir=None) -> SynthesisProblem:
    """Read, check and build the :class:`SynthesisProblem` of a problem file.

    Parameters
    ----------
    path : path-like
        The TOML file.
    fmu_dir : path-like, optional
        The FMU folder (the controller FMU, and the plant FMU if not beside the file).

    Raises
    ------
    ProblemFileError
        One line naming the file, the key and what is wrong.
    """
    from descent_fmus.models.controllers.network_operator import NQ_MAX, NU_MAX, NX_MAX
    from descent_fmus.synthesis.methods.law import (LawFileError, MatrixError,
                                                                  NetworkOperator)
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir

    path = Path(path)
    rd = _Reader(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ProblemFileError(f"{path}: cannot read the problem file: {exc.strerror}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProblemFileError(f"{path}: not valid TOML: {exc}") from None
    fmu_dir = default_fmu_dir() if fmu_dir is None else Path(fmu_dir)
    rd.keys(data, "(top level)", _TOP)

    # [problem]
    prob = rd.table(data, "problem")
    rd.keys(prob, "problem", _KEYS["problem"])
    name = rd.string(prob, "problem", "name")
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]*", name):
        raise rd.error("problem.name", f"use letters, digits, '-' and '_' (starting with a "
                                       f"letter), got {name!r}")

    # [plant]
    plant = rd.table(data, "plant")
    rd.keys(plant, "plant", _KEYS["plant"])
    plant_path = _fmu(rd, "plant.fmu", rd.string(plant, "plant", "fmu"), fmu_dir)
    md = _model_description(rd, "plant.fmu", plant_path)
    pvars = {v.name: v for v in md.modelVariables}
    outputs = {n for n, v in pvars.items() if v.causality == "output"}
    real_outputs = {n for n in outputs if pvars[n].type == "Real"}
    inputs = {n for n, v in pvars.items() if v.causality == "input"}
    settable = {n for n, v in pvars.items() if v.causality in ("parameter", "input")}

    def settable_values(d: dict, key: str) -> dict:
        out = {}
        for k, v in d.items():
            if k not in settable:
                raise rd.error(f"{key}.{k}", f"{md.modelName} has no parameter or input "
                                             f"named {k!r}")
            out[k] = rd.number(d, key, k)
        return out

    fixed = settable_values(rd.table(plant, "plant.parameters", required=False),
                            "plant.parameters")

    # [controller]
    ctrl = rd.table(data, "controller")
    rd.keys(ctrl, "controller", _KEYS["controller"])
    ctrl_path = (_fmu(rd, "controller.fmu", ctrl["fmu"], fmu_dir) if "fmu" in ctrl else None)
    if ctrl_path is None:
        ctrl_path = fmu_dir / "NetworkOperatorController.fmu"
        if not ctrl_path.is_file():
            raise rd.error("controller.fmu", f"the generic controller {ctrl_path} is not "
                                             f"built: run python build_fmus.py (or --fmus DIR)")
    ins, scale, offset = [], [], []
    for key, item in rd.items(ctrl, "controller.inputs", _KEYS["controller.inputs"]):
        o = rd.string(item, key, "output")
        if o not in outputs:
            raise rd.error(f"{key}.output", f"{o!r} is not an output of {md.modelName} "
                                            f"(its outputs: {', '.join(sorted(outputs))})")
        if o not in real_outputs:
            raise rd.error(f"{key}.output", f"{o!r} is a {pvars[o].type} output; the law "
                                            f"reads Real outputs")
        ins.append(o)
        scale.append(float(rd.number(item, key, "scale", 1.0)))
        offset.append(float(rd.number(item, key, "offset", 0.0)))
    outs, bounds = [], []
    for key, item in rd.items(ctrl, "controller.outputs", _KEYS["controller.outputs"]):
        i = rd.string(item, key, "input")
        if i not in inputs:
            raise rd.error(f"{key}.input", f"{i!r} is not an input of {md.modelName} (its "
                                           f"inputs: {', '.join(sorted(inputs)) or 'none'})")
        lo, hi = rd.number(item, key, "min"), rd.number(item, key, "max")
        if lo > hi:
            raise rd.error(key, f"min = {lo} > max = {hi}")
        outs.append(i)
        bounds.append((float(lo), float(hi)))
    if len(ins) > NX_MAX or len(outs) > NU_MAX:
        raise rd.error("controller", f"the NetworkOperatorController reads at most {NX_MAX} "
                                     f"inputs and drives at most {NU_MAX} outputs")

    # [simulation]
    sim = rd.table(data, "simulation")
    rd.keys(sim, "simulation", _KEYS["simulation"])
    step = float(rd.number(sim, "simulation", "step", positive=True))
    stop_time = float(rd.number(sim, "simulation", "stop_time", positive=True))
    if step > stop_time:
        raise rd.error("simulation.step", f"step {step} s exceeds stop_time {stop_time} s")
    stop = None
    if "stop" in sim:
        st = rd.table(sim, "simulation.stop")
        rd.keys(st, "simulation.stop", _KEYS["simulation.stop"])
        so = rd.string(st, "simulation.stop", "output")
        if so not in outputs:
            raise rd.error("simulation.stop.output", f"{so!r} is not an output of "
                                                     f"{md.modelName}")
        op = rd.string(st, "simulation.stop", "op")
        if op not in ("<=", ">=", "!="):
            raise rd.error("simulation.stop.op", f"must be '<=', '>=' or '!=', got {op!r}")
        stop = Stop(so, op, float(rd.number(st, "simulation.stop", "value")))

    # [initial_states]
    init = rd.table(data, "initial_states")
    rd.keys(init, "initial_states", _KEYS["initial_states"])
    if ("states" in init) == ("box" in init):
        raise rd.error("initial_states", "give either 'states' (a list) or 'box' (with "
                                         "'samples')")
    if "states" in init:
        if not isinstance(init["states"], list) or not init["states"]:
            raise rd.error("initial_states.states", "the set of initial states is empty")
        states = []
        for k, s in enumerate(init["states"]):
            if not isinstance(s, dict):
                raise rd.error(f"initial_states.states[{k + 1}]", "must be a table")
            states.append(settable_values(s, f"initial_states.states[{k + 1}]"))
    else:
        from descent_fmus.synthesis.problems.dispersion import METHODS, Box
        box = rd.table(init, "initial_states.box")
        if not box:
            raise rd.error("initial_states.box", "the box is empty")
        ranges = {}
        for k, v in box.items():
            key = f"initial_states.box.{k}"
            if k not in settable:
                raise rd.error(key, f"{md.modelName} has no parameter or input named {k!r}")
            if not (isinstance(v, list) and len(v) == 2 and all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    for x in v)):
                raise rd.error(key, f"must be [min, max] (two finite numbers), got {v!r}")
            if v[0] > v[1]:
                raise rd.error(key, f"min = {v[0]} > max = {v[1]}")
            ranges[k] = (float(v[0]), float(v[1]))
        sampler = rd.string(init, "initial_states", "sampler", "uniform")
        if sampler not in METHODS:
            raise rd.error("initial_states.sampler", f"must be one of {', '.join(METHODS)}, "
                                                     f"got {sampler!r}")
        samples = int(rd.number(init, "initial_states", "samples", 1 if sampler == "corners"
                                else None, positive=True, integer=True))
        seed = int(rd.number(init, "initial_states", "seed", 1, integer=True))
        states = Box.from_bounds(ranges).sample(samples, seed, sampler)
    states = tuple(dict(fixed, **s) for s in states)

    # [[objectives]]
    law_signals = {f"u{k + 1}": f"u[{k + 1}]" for k in range(len(outs))}
    signals = outputs | set(law_signals)
    objectives, names, penalty = [], [], []
    for key, ob in rd.items(data, "objectives", _KEYS["objectives"]):
        oname = rd.string(ob, key, "name")
        if oname in names:
            raise rd.error(f"{key}.name", f"objective {oname!r} appears twice")
        try:
            expr = Expression(rd.string(ob, key, "flight"), signals)
        except ExpressionError as exc:
            raise rd.error(f"{key}.flight", str(exc)) from None
        for fn, sig in expr.reductions:
            if fn != "final" and sig not in law_signals and sig not in real_outputs:
                raise rd.error(f"{key}.flight", f"{fn}({sig}) needs a Real signal; {sig!r} is "
                                                f"{pvars[sig].type}")
        over = rd.string(ob, key, "over_states", "sum")
        if over not in _OVER:
            raise rd.error(f"{key}.over_states", f"must be one of {', '.join(_OVER)}, got "
                                                 f"{over!r}")
        unmet = float(rd.number(ob, key, "unmet_stop_penalty", 0.0))
        if unmet and stop is None:
            raise rd.error(f"{key}.unmet_stop_penalty", "needs [simulation].stop (a flight can "
                                                        "only miss a stop condition it has)")
        objectives.append(_Objective(oname, expr, over, unmet))
        names.append(oname)
        penalty.append(float(rd.number(ob, key, "penalty", 1e9)))
    record = sorted({sig for ob in objectives for fn, sig in ob.expression.reductions
                     if fn != "final" and sig not in law_signals})
    if any(sig in law_signals for ob in objectives for _, sig in ob.expression.reductions):
        record.append("ctrl.u[1]")             # switches recording on (law outputs included)

    # [basic_law]
    bl = rd.table(data, "basic_law")
    rd.keys(bl, "basic_law", _KEYS["basic_law"])
    kinds = [k for k in ("gains", "file", "psi") if k in bl]
    if len(kinds) != 1:
        raise rd.error("basic_law", "give exactly one of 'gains' (a linear law), 'file' (a law "
                                    "JSON) or 'psi' (a matrix inline)")
    common = dict(bounds=bounds, input_names=ins, input_scale=scale, input_offset=offset)
    try:
        if "gains" in bl:
            size = bl.get("size")
            law = NetworkOperator.linear(bl["gains"], bl.get("bias"), size=size, **common)
        elif "file" in bl:
            loaded = NetworkOperator.load(path.parent / bl["file"])
            law = NetworkOperator(loaded.psi, loaded.nx, loaded.q, loaded.outputs, **common)
        else:
            law = NetworkOperator(bl["psi"], len(ins), bl.get("q", []), bl.get("outputs"),
                                  **common)
    except (MatrixError, LawFileError, TypeError, ValueError, OSError) as exc:
        raise rd.error(f"basic_law.{kinds[0]}", str(exc)) from None
    if law.nx != len(ins) or len(law.outputs) != len(outs):
        raise rd.error("basic_law", f"the law reads {law.nx} inputs and has {len(law.outputs)} "
                                    f"outputs; the controller table has {len(ins)} and "
                                    f"{len(outs)}")
    if law.size > 32 or len(law.q) > NQ_MAX:
        raise rd.error("basic_law", f"the law has {law.size} nodes and {len(law.q)} "
                                    f"parameters; the controller FMU holds 32 and {NQ_MAX}")

    # [ga]
    ga = rd.table(data, "ga", required=False)
    rd.keys(ga, "ga", _KEYS["ga"])
    try:
        budget = Budget().with_(**{k: int(rd.number(ga, "ga", k, integer=True))
                                   for k in ("population", "generations", "crossovers", "lchr",
                                             "epoch", "seed") if k in ga})
    except ValueError as exc:
        raise rd.error("ga", str(exc)) from None
    q_lo, q_hi = -16.0, 16.0
    if "q_range" in ga:
        qr = ga["q_range"]
        if not (isinstance(qr, list) and len(qr) == 2 and all(isinstance(x, (int, float))
                                                               for x in qr) and qr[0] < qr[1]):
            raise rd.error("ga.q_range", f"must be [min, max] with min < max, got {qr!r}")
        q_lo, q_hi = float(qr[0]), float(qr[1])
    q_ib, q_fb = 4, 12
    if "q_bits" in ga:
        # up to 48 bits: the Gray code decodes through int64 and float64 (exact to 2^53)
        qb = ga["q_bits"]
        if not (isinstance(qb, list) and len(qb) == 2 and all(isinstance(x, int) and x >= 0
                                                               for x in qb)
                and 1 <= sum(qb) <= 48):
            raise rd.error("ga.q_bits", f"must be [integer bits, fraction bits] with 1 to 48 "
                                        f"bits in all, got {qb!r}")
        q_ib, q_fb = qb
    if any(not q_lo <= v < q_hi for v in law.q):
        raise rd.error("ga.q_range", f"the basic law's parameters {law.q} must lie in "
                                     f"[{q_lo}, {q_hi})")
    ops = {}
    for key, table, default in (("unary", 28, PAPER_UNARY), ("binary", 8, PAPER_BINARY)):
        v = ga.get(key, list(default))
        if not (isinstance(v, list) and v and all(isinstance(x, int) and 1 <= x <= table
                                                  for x in v)):
            raise rd.error(f"ga.{key}", f"must be a non-empty list of operation numbers "
                                        f"1..{table}, got {v!r}")
        ops[key] = tuple(v)

    digest = hashlib.sha256(raw).hexdigest()[:16]
    wiring = Wiring(name=f"{re.sub(r'[^A-Za-z0-9_]', '_', name)}ClosedLoop",
                    plant=md.coSimulation.modelIdentifier, controller="NetworkOperatorController",
                    to_controller=tuple((o, f"x[{k + 1}]") for k, o in enumerate(ins)),
                    to_plant=tuple((f"u[{k + 1}]", i) for k, i in enumerate(outs)),
                    step=step, stop_time=stop_time, stop=stop,
                    exposed=tuple((o, "plant", o) for o in sorted(real_outputs))
                    + tuple((f"u{k + 1}", "controller", f"u[{k + 1}]")
                            for k in range(len(outs))),
                    description=prob.get("description", f"problem {name} ({path.name})"))
    return SynthesisProblem(
        name=name, description=str(prob.get("description", f"problem file {path.name}")),
        wiring=wiring, initial_states=states,
        objectives=FileObjectives(tuple(objectives), tuple(law_signals.items()),
                                  stop is not None),
        objective_names=tuple(names), penalty=tuple(penalty), basic_law=law, budget=budget,
        unary=ops["unary"], binary=ops["binary"], q_bits=(q_ib, q_fb, q_lo, q_hi),
        record=tuple(record), plant_fmu=str(plant_path), controller_fmu=str(ctrl_path),
        source=f"file {path.name} sha256:{digest}")
