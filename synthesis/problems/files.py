"""Synthesis problems from a TOML file, for any FMI 2.0 co-simulation plant FMU.

``descent-fmus synthesize --problem FILE.toml --out DIR`` runs a synthesis on a plant this
package knows nothing about, with the same recipe as a registered problem: the file names the
plant FMU (any tool's), which of its outputs feed the law and which of its inputs the law
drives, the sampling period, when a flight ends, the initial states, the objectives and
constraints, the basic law, and the recipe (budget, GA, CMA-ES refinement and its target, the
baselines). The format, key by key::

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
    # scaling = "auto"                    # the inputs' offsets and scales derived from the basic
                                          # law's flights (where it acts unsaturated)

    [simulation]
    step = 0.1                            # communication step = the law's sample period [s]
    stop_time = 20.0                      # [s]
    stop = { output = "h", op = "<=", value = 0.0 }    # optional; op is "<=", ">=" or "!="
    # path = "container"                  # fly the closed loop as one container FMU

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
    over_states = "sum"                   # sum | mean | max | min over the initial states
    unmet_stop_penalty = 100.0            # added for a flight the stop condition never ended
    penalty = 1e6                         # a law whose evaluation fails gets this

    [[objectives]]                        # a reduction of an expression of signals (evaluated
    name = "effort"                       # at every communication point, then reduced)
    flight = "integral(h**2 + 0.1 * u1**2)"            # quadratic cost (u1: the law's output)

    [[constraints]]                       # optional: feasibility first, then Pareto rank
    name = "soft"
    flight = "max(abs(v))"                # per flight: the peak of |v| (max of ONE argument
    sense = "<="                          # is a reduction; max(a, b) the larger of a and b)
    bound = 2.0
    over_states = "max"                   # max (every start) | min | mean | sum
    # scale = 1.0                         # unit of the violation (default max(|bound|, 1))

    [basic_law]                           # the first basic solution: a linear law ...
    gains = [ [ -1.0, -2.0 ] ]            # one row per output: u_k = sum_i gains[k][i] x_i + bias[k]
    bias = [ 1.0 ]
    size = 16                             # nodes (room for the GA's structure)
    # ... or a law file of a previous synthesis:   file = "law.json"
    # ... or a matrix inline:  psi = [[...]], q = [...], outputs = [...]

    [budget]                              # optional: when a run ends (synthesize --flights ...)
    flights = 2000                        # laws flown (0 = no flight budget)
    generations = 40
    seed = 1
    # seconds = 600                       # wall-clock budget

    [ga]                                  # optional: the variational GA (synthesize --population ...)
    population = 64
    crossovers = 16
    lchr = 6
    epoch = 8
    q_range = [-16.0, 16.0]               # range of the parameters' Gray code (default +-1024)
    q_bits = [4, 12]                      # its integer and fraction bits (default 11 + 31)
    # basis_rule = "target"  elite_trim = 4  p_mutation = 0.7  alpha = 0.4  ksearch = 4
    # unary = [1, 3, 4, 5, 8, 9, 10, 14, 15]   binary = [1, 2, "atan2"]   (numbers or names)

    [refine]                              # optional: CMA-ES on promising laws' parameters
    basis = 400                           # evaluations on the basic solution first
    basis_patience = 1                    # ... on while its restarts improve, if no epoch fits
    evals = 200                           # per refined law after every epoch
    laws = 1                              # laws refined per epoch
    # sigma = 0.3  popsize = 0  starts = 1

    [target]                              # the single objective of CMA-ES (refinement, baselines)
    objective = "miss"                    # minimise this objective ...
    constraint = "fuel"                   # ... subject to this one below the limit (optional)
    limit = 5.0
    # weight = 10.0

    [baselines]                           # fixed structures for synthesize --method cma-NAME
    linear = { kind = "linear" }          # kind: linear | polynomial (degree) | tanh (hidden)
    cubic = { kind = "polynomial", degree = 3 }
    # mine = { kind = "file", file = "law.json" }   (any kind: its own scale = [...], offset = [...])
    [gp]                # optional: the GP baseline (--method gp): population = 200, tournament = 3

``generations`` and ``seed`` are also read from ``[ga]`` (older files).  Every error names the
file, the key and the problem (:class:`ProblemFileError`); nothing is written before the file
has been checked against the plant FMU's model description.
"""
from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

from descent_fmus.synthesis.fmi.closed_loop import Stop, Wiring
from descent_fmus.synthesis.problems.contract import SynthesisProblem
from descent_fmus.synthesis.problems.file_functions import FileObjectives
from descent_fmus.synthesis.problems.file_objectives import (CONSTRAINT_KEYS, OBJECTIVE_KEYS,
                                                             read_constraints, read_objectives,
                                                             recorded_signals)
from descent_fmus.synthesis.problems.file_reader import (ControllerInfo, PlantInfo,
                                                         ProblemFileError, Reader, find_fmu,
                                                         model_description)
from descent_fmus.synthesis.problems.file_recipe import read_baselines, read_recipe, read_target
from descent_fmus.synthesis.problems.runner import Runner
from descent_fmus.synthesis.problems.limits import (MAX_FILE_BYTES, MAX_STATES,
                                                    ResourceLimitError, check_steps)

try:
    import tomllib
except ModuleNotFoundError:              # Python 3.10
    import tomli as tomllib

__all__ = ["ProblemFileError", "load_problem_file", "FileObjectives"]

_TOP = {"problem", "plant", "controller", "simulation", "initial_states", "objectives",
        "constraints", "basic_law", "budget", "ga", "refine", "target", "baselines", "gp"}
_KEYS = {
    "problem": {"name", "description"},
    "plant": {"fmu", "parameters"},
    "controller": {"fmu", "inputs", "outputs", "scaling"},
    "controller.inputs": {"output", "scale", "offset"},
    "controller.outputs": {"input", "min", "max"},
    "simulation": {"step", "stop_time", "stop", "path"},
    "simulation.stop": {"output", "op", "value"},
    "initial_states": {"states", "box", "samples", "sampler", "seed"},
    "objectives": OBJECTIVE_KEYS,
    "constraints": CONSTRAINT_KEYS,
    "basic_law": {"gains", "bias", "size", "file", "psi", "q", "outputs"},
}


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
    from descent_fmus.synthesis.paths import fmu_dir as default_fmu_dir
    path = Path(path)
    rd = Reader(path)
    raw, data = _read_toml(path)
    fmu_dir = default_fmu_dir() if fmu_dir is None else Path(fmu_dir)
    rd.keys(data, "(top level)", _TOP)
    name, description = _problem_table(rd, data, path)
    plant, fixed = _plant_table(rd, data, fmu_dir)
    ctrl = _controller_table(rd, data, plant, fmu_dir)
    step, stop_time, stop, runner = _simulation_table(rd, data, plant)
    states = tuple(dict(fixed, **s) for s in _initial_states(rd, data, plant))
    signals = plant.outputs | set(ctrl.law_signals)
    objectives, names, penalty = read_objectives(rd, data, plant, ctrl, signals, stop)
    constraints = read_constraints(rd, data, plant, ctrl, signals, stop)
    record, initial = recorded_signals([ob.flight.expression for ob in objectives] +
                                       [c.flight.expression for c in constraints], ctrl)
    law = _basic_law(rd, data, path, ctrl)
    recipe, q_bits, ops = read_recipe(rd, data, law)
    digest = hashlib.sha256(raw).hexdigest()[:16]
    wiring = _wiring(name, description, path, plant, ctrl, step, stop_time, stop)
    return SynthesisProblem(
        name=name, description=description or f"problem file {path.name}",
        wiring=wiring, initial_states=states, objectives=FileObjectives(tuple(objectives)),
        objective_names=tuple(names), penalty=tuple(penalty), basic_law=law, **recipe,
        constraints=tuple(constraints), target=read_target(rd, data, names),
        baselines=read_baselines(rd, data, path, law), unary=ops["unary"], binary=ops["binary"],
        q_bits=q_bits, record=record, initial=initial, plant_fmu=str(plant.path),
        controller_fmu=str(ctrl.path), runner=runner, input_scaling=ctrl.scaling,
        source=f"file {path.name} sha256:{digest}")


def _read_toml(path: Path) -> tuple:
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ProblemFileError(f"{path}: {size} bytes; a problem file holds at most "
                                   f"{MAX_FILE_BYTES} (list many initial states as a box)")
        raw = path.read_bytes()
    except OSError as exc:
        raise ProblemFileError(f"{path}: cannot read the problem file: {exc.strerror}") from None
    try:
        return raw, tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProblemFileError(f"{path}: not valid TOML: {exc}") from None


def _problem_table(rd: Reader, data, path: Path) -> tuple:
    prob = rd.table(data, "problem")
    rd.keys(prob, "problem", _KEYS["problem"])
    name = rd.string(prob, "problem", "name")
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]*", name):
        raise rd.error("problem.name", f"use letters, digits, '-' and '_' (starting with a "
                                       f"letter), got {name!r}")
    description = prob.get("description", "")
    if not isinstance(description, str):
        raise rd.error("problem.description", f"must be a string, got {description!r}")
    return name, description


def _settable_values(rd: Reader, plant: PlantInfo, d: dict, key: str) -> dict:
    out = {}
    for k in d:
        if k not in plant.settable:
            raise rd.error(f"{key}.{k}", f"{plant.md.modelName} has no parameter or input "
                                         f"named {k!r}")
        out[k] = float(rd.number(d, key, k))
    return out


def _plant_table(rd: Reader, data, fmu_dir) -> tuple:
    table = rd.table(data, "plant")
    rd.keys(table, "plant", _KEYS["plant"])
    path = find_fmu(rd, "plant.fmu", rd.string(table, "plant", "fmu"), fmu_dir)
    md = model_description(rd, "plant.fmu", path)
    plant = PlantInfo(path, md, {v.name: v for v in md.modelVariables})
    fixed = _settable_values(rd, plant, rd.table(table, "plant.parameters", required=False),
                             "plant.parameters")
    return plant, fixed


def _controller_table(rd: Reader, data, plant: PlantInfo, fmu_dir) -> ControllerInfo:
    from descent_fmus.models.controllers.network_operator import NU_MAX, NX_MAX
    table = rd.table(data, "controller")
    rd.keys(table, "controller", _KEYS["controller"])
    if "fmu" in table:
        path = find_fmu(rd, "controller.fmu", table["fmu"], fmu_dir)
    else:
        path = (Path(fmu_dir) / "NetworkOperatorController.fmu").resolve()
        if not path.is_file():
            raise rd.error("controller.fmu", f"the generic controller {path} is not built: run "
                                             f"python build_fmus.py (or --fmus DIR)")
    ctrl = ControllerInfo(path, [], [], [], [], [])
    name = plant.md.modelName
    for key, item in rd.items(table, "controller.inputs", _KEYS["controller.inputs"]):
        o = rd.string(item, key, "output")
        if o not in plant.outputs:
            raise rd.error(f"{key}.output", f"{o!r} is not an output of {name} (its outputs: "
                                            f"{', '.join(sorted(plant.outputs))})")
        if o not in plant.real_outputs:
            raise rd.error(f"{key}.output", f"{o!r} is a {plant.vars[o].type} output; the law "
                                            f"reads Real outputs")
        ctrl.inputs.append(o)
        ctrl.scale.append(float(rd.number(item, key, "scale", 1.0)))
        ctrl.offset.append(float(rd.number(item, key, "offset", 0.0)))
    for key, item in rd.items(table, "controller.outputs", _KEYS["controller.outputs"]):
        i = rd.string(item, key, "input")
        if i not in plant.inputs:
            raise rd.error(f"{key}.input", f"{i!r} is not an input of {name} (its inputs: "
                                           f"{', '.join(sorted(plant.inputs)) or 'none'})")
        lo, hi = rd.number(item, key, "min"), rd.number(item, key, "max")
        if lo > hi:
            raise rd.error(key, f"min = {lo} > max = {hi}")
        ctrl.outputs.append(i)
        ctrl.bounds.append((float(lo), float(hi)))
    ctrl.scaling = rd.string(table, "controller", "scaling", "given")
    if ctrl.scaling not in ("given", "auto"):
        raise rd.error("controller.scaling", f"must be 'given' (the scales and offsets of the "
                                             f"inputs table) or 'auto', got {ctrl.scaling!r}")
    if len(ctrl.inputs) > NX_MAX or len(ctrl.outputs) > NU_MAX:
        raise rd.error("controller", f"the NetworkOperatorController reads at most {NX_MAX} "
                                     f"inputs and drives at most {NU_MAX} outputs")
    return ctrl


def _simulation_table(rd: Reader, data, plant: PlantInfo) -> tuple:
    sim = rd.table(data, "simulation")
    rd.keys(sim, "simulation", _KEYS["simulation"])
    step = float(rd.number(sim, "simulation", "step", positive=True))
    stop_time = float(rd.number(sim, "simulation", "stop_time", positive=True))
    if step > stop_time:
        raise rd.error("simulation.step", f"step {step} s exceeds stop_time {stop_time} s")
    try:
        check_steps(stop_time, step, "stop_time / step")
    except ResourceLimitError as exc:
        raise rd.error("simulation", str(exc)) from None
    stop = None
    if "stop" in sim:
        st = rd.table(sim, "simulation.stop")
        rd.keys(st, "simulation.stop", _KEYS["simulation.stop"])
        so = rd.string(st, "simulation.stop", "output")
        if so not in plant.outputs:
            raise rd.error("simulation.stop.output", f"{so!r} is not an output of "
                                                     f"{plant.md.modelName} (its outputs: "
                                                     f"{', '.join(sorted(plant.outputs))})")
        op = rd.string(st, "simulation.stop", "op")
        if op not in ("<=", ">=", "!="):
            raise rd.error("simulation.stop.op", f"must be '<=', '>=' or '!=', got {op!r}")
        stop = Stop(so, op, float(rd.number(st, "simulation.stop", "value")))
    path = rd.string(sim, "simulation", "path", "master")
    if path not in ("master", "container"):
        raise rd.error("simulation.path", f"must be 'master' (the fmpy master steps both FMUs) "
                                          f"or 'container' (one container FMU), got {path!r}")
    return step, stop_time, stop, Runner(container=path == "container")


def _initial_states(rd: Reader, data, plant: PlantInfo) -> list:
    init = rd.table(data, "initial_states")
    rd.keys(init, "initial_states", _KEYS["initial_states"])
    if ("states" in init) == ("box" in init):
        raise rd.error("initial_states", "give either 'states' (a list) or 'box' (with "
                                         "'samples')")
    if "states" in init:
        if not isinstance(init["states"], list) or not init["states"]:
            raise rd.error("initial_states.states", "the set of initial states is empty")
        if len(init["states"]) > MAX_STATES:
            raise rd.error("initial_states.states", f"{len(init['states'])} states; the "
                                                    f"documented maximum is {MAX_STATES}")
        states = []
        for k, s in enumerate(init["states"]):
            if not isinstance(s, dict):
                raise rd.error(f"initial_states.states[{k + 1}]", "must be a table")
            states.append(_settable_values(rd, plant, s, f"initial_states.states[{k + 1}]"))
        return states
    return _sampled_states(rd, init, plant)


def _sampled_states(rd: Reader, init: dict, plant: PlantInfo) -> list:
    from descent_fmus.synthesis.problems.dispersion import METHODS, Box
    box = rd.table(init, "initial_states.box")
    if not box:
        raise rd.error("initial_states.box", "the box is empty")
    ranges = {}
    for k, v in box.items():
        key = f"initial_states.box.{k}"
        if k not in plant.settable:
            raise rd.error(key, f"{plant.md.modelName} has no parameter or input named {k!r}")
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
    try:
        return Box.from_bounds(ranges).sample(samples, seed, sampler)
    except ValueError as exc:
        raise rd.error("initial_states.samples", str(exc)) from None


def _basic_law(rd: Reader, data, path: Path, ctrl: ControllerInfo):
    from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX
    bl = rd.table(data, "basic_law")
    rd.keys(bl, "basic_law", _KEYS["basic_law"])
    kinds = [k for k in ("gains", "file", "psi") if k in bl]
    if len(kinds) != 1:
        raise rd.error("basic_law", "give exactly one of 'gains' (a linear law), 'file' (a law "
                                    "JSON) or 'psi' (a matrix inline)")
    if "size" in bl and not (isinstance(bl["size"], int) and 1 <= bl["size"] <= L_MAX):
        raise rd.error("basic_law.size", f"must be an integer in 1..{L_MAX} (the nodes the "
                                         f"controller FMU holds), got {bl['size']!r}")
    law = _law(rd, bl, kinds[0], path, ctrl, f"basic_law.{kinds[0]}")
    if law.size > 32 or len(law.q) > NQ_MAX:
        raise rd.error("basic_law", f"the law has {law.size} nodes and {len(law.q)} "
                                    f"parameters; the controller FMU holds 32 and {NQ_MAX}")
    return law


def _law(rd: Reader, table: dict, kind: str, path: Path, ctrl: ControllerInfo, key: str,
         scale=None, offset=None):
    """A law of the controller's inputs and outputs from ``table`` (gains, file or psi)."""
    from descent_fmus.synthesis.methods.law import LawFileError, MatrixError, NetworkOperator
    common = dict(bounds=ctrl.bounds, input_names=ctrl.inputs,
                  input_scale=ctrl.scale if scale is None else scale,
                  input_offset=ctrl.offset if offset is None else offset)
    try:
        if kind == "gains":
            law = NetworkOperator.linear(table["gains"], table.get("bias"),
                                         size=table.get("size"), **common)
        elif kind == "file":
            loaded = NetworkOperator.load(path.parent / table["file"])
            law = NetworkOperator(loaded.psi, loaded.nx, loaded.q, loaded.outputs, **common)
        else:
            law = NetworkOperator(table["psi"], len(ctrl.inputs), table.get("q", []),
                                  table.get("outputs"), **common)
    except (MatrixError, LawFileError, TypeError, ValueError, OSError) as exc:
        raise rd.error(key, str(exc)) from None
    if law.nx != len(ctrl.inputs) or len(law.outputs) != len(ctrl.outputs):
        raise rd.error(key, f"the law reads {law.nx} inputs and has {len(law.outputs)} outputs; "
                            f"the controller table has {len(ctrl.inputs)} and "
                            f"{len(ctrl.outputs)}")
    return law


def _wiring(name, description, path, plant: PlantInfo, ctrl: ControllerInfo, step, stop_time,
            stop) -> Wiring:
    outs = ctrl.outputs
    return Wiring(name=f"{re.sub(r'[^A-Za-z0-9_]', '_', name)}ClosedLoop",
                  plant=plant.md.coSimulation.modelIdentifier,
                  controller="NetworkOperatorController",
                  to_controller=tuple((o, f"x[{k + 1}]") for k, o in enumerate(ctrl.inputs)),
                  to_plant=tuple((f"u[{k + 1}]", i) for k, i in enumerate(outs)),
                  step=step, stop_time=stop_time, stop=stop,
                  exposed=tuple((o, "plant", o) for o in sorted(plant.real_outputs))
                  + tuple((f"u{k + 1}", "controller", f"u[{k + 1}]")
                          for k in range(len(outs))),
                  description=description or f"problem {name} ({path.name})")
