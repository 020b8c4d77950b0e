"""What a synthesis solves: the problem contract every problem shares.

A :class:`SynthesisProblem` names the closed loop (a :class:`~synthesis.fmi.closed_loop.Wiring`
of a plant FMU and the generic ``NetworkOperatorController`` FMU), the initial states every
candidate law is flown from, and what is computed from those flights:

* **objectives** -- ``objectives(flights) -> (f, extras)``: each flight is a
  :class:`~synthesis.fmi.closed_loop.ClosedLoopResult` that carries the start values it was
  flown from (``flight.start``), so an objective never re-zips results with its own copy of the
  initial states;
* **constraints** -- :class:`Constraint`: a per-flight value with a bound, aggregated over the
  initial states; their total violation ranks before the objectives everywhere
  (constraint-domination, :mod:`synthesis.methods.pareto`);
* the **recipe**: the basic law the search starts from, its :class:`Budget` (flights,
  generations, wall time, seed), the GA's sizes (:class:`~synthesis.methods.ga_config.GAConfig`),
  the CMA-ES refinement (:class:`~synthesis.methods.refinement.RefineConfig`), the CMA-ES
  target, the fixed-structure baselines.

Problems come from two places -- the systems of this package (``synthesis/systems/<stem>/``) and
problem files for any FMI 2.0 co-simulation plant (:mod:`synthesis.problems.files`) -- and a file
can say everything a registered problem says.  A problem is sent to worker processes as it is,
so everything in it must pickle (module-level functions, plain objects).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult, Wiring
from descent_fmus.synthesis.methods.gp_config import GPConfig
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.pareto import Target
from descent_fmus.synthesis.methods.refinement import RefineConfig
from descent_fmus.synthesis.methods.settings import (SettingError, check_settings,
                                                     replace_settings, setting)
from descent_fmus.synthesis.methods.ga_config import PAPER_BINARY, PAPER_UNARY, GAConfig
from descent_fmus.synthesis.problems.runner import Runner

__all__ = ["Budget", "Constraint", "Outcome", "ProblemOption", "Report", "SynthesisProblem",
           "ObjectiveFunction", "SETTING_GROUPS", "INVALID_VIOLATION", "AGGREGATES",
           "start_values", "recipe", "DEFAULT_Q_BITS", "LAB_SEARCH"]

#: ``objectives(flights) -> (f, extras)``: ``flights`` one ClosedLoopResult per initial state
#: flown (``flight.start`` its start values), ``f`` the objective vector (finite floats),
#: ``extras`` reported values (JSON-able scalars).
ObjectiveFunction = Callable[[Sequence[ClosedLoopResult]], tuple]

#: The Gray code of the parameters by default [choice]: 11 + 31 bits over [-1024, 1024) -- wide
#: enough for the gains a CMA-ES refinement drives to (S5: 871), fine enough (4.7e-10) not to
#: stall it (S1 stalled on a grid of 3.8e-6, S5 on 4.9e-4).
DEFAULT_Q_BITS = (11, 31, -1024.0, 1024.0)

#: The structure search as it was measured before its restarts and form tuning existed:
#: one refined law per epoch, children with their parents' parameters, no restarts.  The
#: registered S1 and S5 recipes keep it [choice]: their bounds and pinned fronts were measured
#: with it (``recipe(..., **LAB_SEARCH)``; ``synthesize --refine-forms 0 --basis-q 0
#: --restart-epochs 0`` on any problem).
LAB_SEARCH = {"refine_forms": 0, "basis_q": 0.0, "restart_epochs": 0}

#: Violation of a constraint whose value cannot be computed (never a NaN in a result).
INVALID_VIOLATION = 1e9

#: How a per-flight value is aggregated over the initial states.
AGGREGATES = {"max": max, "min": min, "sum": sum, "mean": lambda v: sum(v) / len(v)}


@dataclass(frozen=True)
class Budget:
    """How much a run spends; the run loop ends at the first limit reached."""

    flights: int = setting(5000, "flight budget: laws flown, each over all the problem's "
                                 "initial states (0 = none; a cma-* method needs one)",
                           0, 10_000_000)
    generations: int = setting(1000, "generations of the variational GA (a fixed-structure "
                                     "search ends by flights)", 0, 10_000_000)
    seconds: float = setting(0.0, "wall-clock budget [s] (0 = none): the run ends at the first "
                                  "step past it", 0.0, 1e8)
    seed: int = setting(1, "random seed; same seed, same result", 0, 2 ** 32 - 1)

    def __post_init__(self):
        check_settings(self, "budget.")


#: The settings of a problem's recipe: (table / attribute, dataclass, command-line prefix).
#: The CLI options of ``synthesize`` and the tables of problem files are derived from it.
SETTING_GROUPS = (("budget", Budget, ""), ("ga", GAConfig, ""), ("refine", RefineConfig,
                                                                  "refine_"),
                  ("gp", GPConfig, "gp_"))


@dataclass(frozen=True)
class Constraint:
    """A per-flight value that must stay within a bound, aggregated over the initial states.

    Attributes
    ----------
    name : str
    flight : callable
        ``flight(result) -> float`` for one flight (module-level or picklable).
    bound : float
    sense : {"<=", ">="}
        The aggregated value must be ``<= bound`` (or ``>= bound``).
    over_states : {"max", "min", "mean", "sum"}
        Aggregate over the flights of a law (e.g. "max": every start must meet the bound).
    scale : float, optional
        Unit of the violation (default ``max(|bound|, 1)``), so that constraints of different
        units add up to one total violation.
    """

    name: str
    flight: Callable
    bound: float
    sense: str = "<="
    over_states: str = "max"
    scale: float | None = None

    def __post_init__(self):
        if self.sense not in ("<=", ">="):
            raise ValueError(f"constraint {self.name}: sense must be '<=' or '>=', got "
                             f"{self.sense!r}")
        if self.over_states not in AGGREGATES:
            raise ValueError(f"constraint {self.name}: over_states must be one of "
                             f"{', '.join(AGGREGATES)}, got {self.over_states!r}")
        if not math.isfinite(self.bound) or (self.scale is not None and not self.scale > 0):
            raise ValueError(f"constraint {self.name}: need a finite bound and a scale > 0")

    def value(self, flights) -> float:
        """The aggregated value over ``flights``."""
        return float(AGGREGATES[self.over_states]([float(self.flight(f)) for f in flights]))

    def violation(self, value: float) -> float:
        """How far ``value`` lies outside the bound, in units of :attr:`scale` (0 = met)."""
        if not math.isfinite(value):
            return INVALID_VIOLATION
        excess = value - self.bound if self.sense == "<=" else self.bound - value
        scale = self.scale if self.scale is not None else max(abs(self.bound), 1.0)
        return min(max(excess, 0.0) / scale, INVALID_VIOLATION)


@dataclass(frozen=True)
class Outcome:
    """What one law's flights gave: objectives, total constraint violation, reported values."""

    f: tuple
    cv: float
    extras: dict


@dataclass(frozen=True)
class ProblemOption:
    """A variant of a problem the command line can choose (``synthesize --option NAME=VALUE``),
    e.g. the statistic of the miss over a sample set: ``apply(problem, value)`` returns the
    variant (ValueError with a one-line message for a bad value)."""

    name: str
    help: str
    apply: Callable


class Report:
    """Problem-specific parts of a synthesis report; the default adds nothing.

    Subclasses override what applies: :meth:`headline` (fields of the progress bar) and
    :meth:`summary` (fields of ``summary.json`` and of the printed report).
    """

    def headline(self, front: np.ndarray) -> dict:
        """Progress-bar fields from the non-dominated laws so far (rows of objective vectors)."""
        return {}

    def summary(self, rows: list, out: Path | None, reference: bool = True) -> dict:
        """Report fields of a finished run.

        ``rows`` are the Pareto laws (objectives, extras and ``formula`` per row), ``out`` the
        run folder (for cached reference data), ``reference`` whether an expensive reference
        (e.g. a bound) may be computed.
        """
        return {}

    def lines(self, summary: dict) -> list:
        """Printed lines for the fields :meth:`summary` added."""
        return []


@dataclass(frozen=True)
class SynthesisProblem:
    """A synthesis problem; see the module docstring.

    Attributes
    ----------
    name : str
        Name (``descent-fmus synthesize NAME``).
    description : str
    wiring : Wiring
        Plant/controller connections, communication step, stop time and stop condition.
    initial_states : tuple of dict
        Plant start values, one dict per initial state (every law flies from each).
    objectives : callable
        :data:`ObjectiveFunction`.
    objective_names : tuple of str
    penalty : tuple of float
        Objectives of a law whose evaluation failed (an FMU error on that law).
    basic_law : NetworkOperator or callable
        The search's first basic solution, or a function returning it (read when first
        needed, e.g. from a law file, so that building the registry reads no file).
    budget, ga, refine, gp : Budget, GAConfig, RefineConfig, GPConfig
        The recipe of a default run (``gp``: the genetic-programming baseline's; ``synthesize``
        overrides single fields: :meth:`tuned`).
    constraints : tuple of Constraint
    target : Target or None
        The single objective of CMA-ES (refinement inside the GA, fixed-structure baselines),
        e.g. J1 subject to J2 < 1 km.
    baselines : callable or None
        ``() -> {name: NetworkOperator}``: fixed law structures whose parameters CMA-ES tunes
        (``synthesize --method cma-NAME``).
    objective_labels : tuple of str
        Axis labels of the plots (default: the names).
    unary, binary : tuple of int
        Operations the variations may use.
    q_bits : tuple
        ``(int_bits, frac_bits, lo, hi)`` of the Gray coding of the parameters q.
    report : Report
    record : tuple of str
        Plant outputs recorded at every communication point of every flight (for objectives
        over the whole flight); empty = only the final outputs are read (fastest).
    initial : tuple of str
        Plant outputs read at t = 0 only (an objective's ``initial(...)`` of them): the C
        master reads them there (no recording); any other loop records them.
    plant_fmu, controller_fmu : str or None
        FMU files; None = ``<wiring.plant>.fmu`` / ``<wiring.controller>.fmu`` in the FMU folder.
        A relative path is taken relative to the FMU folder.
    source : str
        Where the problem comes from (a registered system, or a problem file and its hash).
    runner : Runner
        How a law is flown (the closed-loop path, racing over the initial states).
    options : tuple of ProblemOption
        Variants the command line can choose.
    input_scaling : {"given", "auto"}
        The basic law's input coordinates as given, or derived from its flights before the
        search (:mod:`synthesis.run.scaling`).
    controller_values : tuple of (str, float)
        Controller start values every flight sets over the law's own (a mode of the controller
        the laws are searched for, e.g. the guided controller's on-board re-planner).
    """

    name: str
    description: str
    wiring: Wiring
    initial_states: tuple
    objectives: ObjectiveFunction
    objective_names: tuple
    penalty: tuple
    basic_law: NetworkOperator | Callable
    budget: Budget = Budget()
    ga: GAConfig = GAConfig()
    refine: RefineConfig = RefineConfig()
    gp: GPConfig = GPConfig()
    constraints: tuple = ()
    target: Target | None = None
    baselines: Callable | None = None
    objective_labels: tuple = ()
    unary: tuple = PAPER_UNARY
    binary: tuple = PAPER_BINARY
    q_bits: tuple = DEFAULT_Q_BITS
    report: Report = field(default_factory=Report)
    record: tuple = ()
    initial: tuple = ()
    plant_fmu: str | None = None
    controller_fmu: str | None = None
    source: str = ""
    runner: Runner = Runner()
    options: tuple = ()
    input_scaling: str = "given"
    controller_values: tuple = ()

    def __post_init__(self):
        for pair in self.controller_values:
            if len(pair) != 2 or not isinstance(pair[0], str) \
                    or not math.isfinite(float(pair[1])):
                raise ValueError(f"problem {self.name!r}: controller_values must be (name, "
                                 f"finite number) pairs, got {pair!r}")
        if self.input_scaling not in ("given", "auto"):
            raise ValueError(f"problem {self.name!r}: input_scaling must be 'given' or 'auto', "
                             f"got {self.input_scaling!r}")
        if not self.initial_states:
            raise ValueError(f"problem {self.name!r}: the set of initial states is empty")
        if len(self.penalty) != len(self.objective_names):
            raise ValueError(f"problem {self.name!r}: {len(self.objective_names)} objectives "
                             f"but {len(self.penalty)} penalty values")

    def basic(self) -> NetworkOperator:
        """The first basic solution (``basic_law``, called if it is a function); with weighted
        arcs on (``ga.weighted_arcs``) a linear one gets room for them
        (:func:`synthesis.methods.structures.with_room`: the same function)."""
        law = self.basic_law
        law = law if isinstance(law, NetworkOperator) else law()
        if self.ga.weighted_arcs:
            from descent_fmus.synthesis.methods.structures import with_room
            law = with_room(law)
        return law

    @property
    def labels(self) -> tuple:
        return self.objective_labels or self.objective_names

    def fmu_paths(self, fmu_dir) -> tuple[Path, Path]:
        """(plant FMU, controller FMU) paths, relative names resolved in ``fmu_dir``."""
        d = Path(fmu_dir)
        plant = Path(self.plant_fmu) if self.plant_fmu else Path(f"{self.wiring.plant}.fmu")
        ctrl = (Path(self.controller_fmu) if self.controller_fmu
                else Path(f"{self.wiring.controller}.fmu"))
        return (plant if plant.is_absolute() else d / plant,
                ctrl if ctrl.is_absolute() else d / ctrl)

    def load(self, plant_fmu, controller_fmu):
        """This problem's closed loop on these FMUs, loaded once (the path its runner chooses;
        a :class:`synthesis.fmi.loop.Loop`)."""
        return self.runner.load(self.wiring, plant_fmu, controller_fmu, record=self.record,
                                initial=self.initial)

    def fly(self, loop, law) -> Outcome:
        """``law`` flown in ``loop`` (:meth:`load`) from this problem's initial states (or
        fewer, racing) -> its :class:`Outcome`: the one call a flight makes on its problem."""
        return self.evaluate(self.runner.flights(loop, self, law))

    def evaluate(self, flights: Sequence[ClosedLoopResult]) -> Outcome:
        """One law's :class:`Outcome` from its flights; a non-finite objective gives the
        penalty (never a NaN in a result)."""
        f, extras = self.objectives(flights)
        f = tuple(float(v) for v in f)
        extras = dict(extras)
        if not all(math.isfinite(v) for v in f):
            f, extras["failed"] = tuple(self.penalty), "non-finite objectives"
        cv = 0.0
        for c in self.constraints:
            value = c.value(flights)
            extras[c.name] = value if math.isfinite(value) else None
            cv += c.violation(value)
        return Outcome(f, cv, extras)

    def failed(self, extras: Mapping) -> Outcome:
        """The :class:`Outcome` of a law whose evaluation failed: the penalty, infeasible."""
        return Outcome(tuple(self.penalty), INVALID_VIOLATION if self.constraints else 0.0,
                       dict(extras, failed=True))

    def with_(self, **changes) -> "SynthesisProblem":
        return replace(self, **changes)

    def tuned(self, **changes) -> "SynthesisProblem":
        """A copy with settings of the recipe changed by name (:data:`SETTING_GROUPS`:
        ``population=64``, ``flights=2000``, ``refine_evals=100``; None values are ignored).

        Raises
        ------
        SettingError
            An unknown name or a value outside its documented range (the message names it).
        """
        return replace(self, **recipe(self, **changes))

    def with_option(self, name: str, value: str) -> "SynthesisProblem":
        """The variant of this problem with option ``name`` (ValueError if it has none such)."""
        for opt in self.options:
            if opt.name == name:
                return opt.apply(self, value)
        known = ", ".join(o.name for o in self.options) or "none"
        raise ValueError(f"problem {self.name} has no option {name!r} (its options: {known})")


def start_values(states: Sequence[Mapping]) -> tuple:
    """Initial states as a tuple of plain dicts of floats (what the problem stores)."""
    return tuple({k: float(v) for k, v in s.items()} for s in states)


def _group_of(key: str) -> tuple:
    """``(attribute, field name)`` of a setting named as on the command line."""
    for attr, cls, prefix in SETTING_GROUPS:
        name = key[len(prefix):] if key.startswith(prefix) else None
        if name is not None and name in cls.__dataclass_fields__:
            return attr, name
    raise SettingError(key, "unknown setting")


def recipe(base: SynthesisProblem | None = None, **settings) -> dict:
    """``{"budget": Budget, "ga": GAConfig, "refine": RefineConfig}`` with ``settings`` named as
    on the command line (``population=128``, ``flights=20000``, ``refine_evals=2000``) applied
    to ``base``'s (default: the defaults); None values are ignored.

    Raises
    ------
    SettingError
        An unknown name or a value outside its documented range (the message names it).
    """
    groups: dict = {}
    for key, value in settings.items():
        if value is not None:
            attr, name = _group_of(key)
            groups.setdefault(attr, {})[name] = value
    out = {}
    for attr, cls, _ in SETTING_GROUPS:
        current = getattr(base, attr) if base is not None else cls()
        out[attr] = replace_settings(current, groups.get(attr, {}), f"{attr}.")
    return out
