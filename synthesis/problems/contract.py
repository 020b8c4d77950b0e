"""What a network-operator synthesis solves: :class:`SynthesisProblem`, its :class:`Budget` and
:class:`Report`.

A problem names the closed loop (a :class:`~synthesis.fmi.closed_loop.Wiring` of a plant FMU and the
generic ``NetworkOperatorController`` FMU), the initial states every candidate law is flown from,
the objectives computed from those flights, the basic law the variational GA starts from and the
budget of a default run.  The evaluator needs nothing else: it knows no plant.

Problems come from two places: the systems of this package (``synthesis/systems/<stem>/``) and
declarative problem files for any FMI 2.0 co-simulation plant (:mod:`synthesis.problems.files`).
A problem is sent to worker processes as it is, so everything in it must pickle (module-level
functions, plain objects).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from descent_fmus.synthesis.fmi.closed_loop import ClosedLoopResult, Wiring
from descent_fmus.synthesis.methods.ga import GAConfig
from descent_fmus.synthesis.methods.law import NetworkOperator

__all__ = ["Budget", "Report", "SynthesisProblem", "ObjectiveFunction"]

#: ``objectives(results) -> (f, extras)``: ``results`` one ClosedLoopResult per initial state,
#: ``f`` the objective vector (finite floats), ``extras`` reported values (JSON-able scalars).
ObjectiveFunction = Callable[[Sequence[ClosedLoopResult]], tuple]

#: The operations the variations may use by default: the paper's set (seed numbering).
PAPER_UNARY = (1, 3, 4, 5, 8, 9, 10, 14, 15)
PAPER_BINARY = (1, 2)


@dataclass(frozen=True)
class Budget:
    """How much a synthesis run spends: GA sizes, generations and the random seed.

    A problem carries its default budget; the command line overrides single fields.
    """

    population: int = 256
    generations: int = 400
    crossovers: int = 32      #: crossover attempts per generation (4 children each)
    lchr: int = 8             #: variations per individual (0 = parameters of the basic law only)
    epoch: int = 12           #: generations between changes of the basic solution
    seed: int = 1
    elite_trim: int = 4       #: Pareto members whose variation lists are trimmed per epoch
    refine_evals: int = 0     #: CMA-ES evaluations per refined law and epoch (0 = GA only)
    refine_laws: int = 1      #: laws whose parameters CMA-ES refines per epoch
    refine_basis: int = 0     #: CMA-ES evaluations on the basic solution before the structure
                              #: search (0 = none)
    flights: int = 0          #: flight budget: cma-* runs fly this many; the GA stops there
                              #: too (0 = by generations only)
    basis_rule: str = "compromise"  #: the epoch's new basis (GAConfig.basis_rule)

    def __post_init__(self):
        if self.generations < 0:
            raise ValueError(f"generations must be >= 0, got {self.generations}")
        if self.flights < 0:
            raise ValueError(f"flights must be >= 0, got {self.flights}")
        self.ga_config()          # validates the GA sizes

    def ga_config(self) -> GAConfig:
        return GAConfig(population=self.population, crossovers=self.crossovers,
                        lchr=self.lchr, epoch=self.epoch, elite_trim=self.elite_trim,
                        refine_evals=self.refine_evals, refine_laws=self.refine_laws,
                        refine_basis=self.refine_basis, basis_rule=self.basis_rule)

    def with_(self, **changes) -> "Budget":
        """A copy with the given fields changed (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in changes.items() if v is not None})


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
    """A network-operator synthesis problem; see the module docstring.

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
        The GA's first basic solution, or a function returning it (read when first needed, e.g.
        from a law file, so that building the registry reads no file); :meth:`basic` gives it.
    budget : Budget
        Default budget of ``synthesize``.
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
    plant_fmu, controller_fmu : str or None
        FMU files; None = ``<wiring.plant>.fmu`` / ``<wiring.controller>.fmu`` in the FMU folder.
        A relative path is taken relative to the FMU folder.
    source : str
        Where the problem comes from (a registered system, or a problem file and its hash).
    target : Target or None
        The single objective of CMA-ES (parameter refinement inside the GA, fixed-structure
        baselines), e.g. J1 subject to J2 < 1 km (:class:`synthesis.methods.baselines.Target`).
    baselines : callable or None
        ``() -> {name: NetworkOperator}``: fixed law structures whose parameters CMA-ES tunes
        (``synthesize --method cma-NAME``), the comparison for the network-operator search.
    runner : Runner or None
        How a law is flown (:class:`synthesis.fmi.container_loop.Runner`: the closed-loop container FMU
        instead of the Python master, racing over the initial states); None = every initial
        state through :class:`~synthesis.fmi.closed_loop.ClosedLoop`.
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
    objective_labels: tuple = ()
    unary: tuple = PAPER_UNARY
    binary: tuple = PAPER_BINARY
    q_bits: tuple = (4, 12, 0.0, 16.0)
    report: Report = field(default_factory=Report)
    record: tuple = ()
    plant_fmu: str | None = None
    controller_fmu: str | None = None
    source: str = ""
    target: object = None
    baselines: Callable | None = None
    runner: object = None

    def __post_init__(self):
        if not self.initial_states:
            raise ValueError(f"problem {self.name!r}: the set of initial states is empty")
        if len(self.penalty) != len(self.objective_names):
            raise ValueError(f"problem {self.name!r}: {len(self.objective_names)} objectives "
                             f"but {len(self.penalty)} penalty values")

    def basic(self) -> NetworkOperator:
        """The GA's first basic solution (``basic_law``, called if it is a function)."""
        law = self.basic_law
        return law if isinstance(law, NetworkOperator) else law()

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

    def evaluate_flights(self, results: Sequence[ClosedLoopResult]) -> tuple:
        """``(f, extras)`` of one law from its flights (the objective function, checked)."""
        f, extras = self.objectives(results)
        return tuple(float(v) for v in f), dict(extras)

    def with_(self, **changes) -> "SynthesisProblem":
        return replace(self, **changes)


def start_values(states: Sequence[Mapping]) -> tuple:
    """Initial states as a tuple of plain dicts of floats (what the problem stores)."""
    return tuple({k: float(v) for k, v in s.items()} for s in states)
