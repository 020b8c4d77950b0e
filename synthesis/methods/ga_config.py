"""The variational GA's settings: its sizes and rates (:class:`GAConfig`) and the operation sets
its variations may use (the paper's, the authors' wider one).

The algorithm that reads them is :class:`~synthesis.methods.variational_ga.VariationalGA`.
"""
from __future__ import annotations

from dataclasses import dataclass

from descent_fmus.synthesis.methods.settings import check_settings, setting

__all__ = ["GAConfig", "PAPER_UNARY", "PAPER_BINARY", "WIDE_UNARY", "WIDE_BINARY",
           "FILE_UNARY", "FILE_BINARY"]

#: The operations the variations may use by default: the paper's set (the seeds' numbering).
PAPER_UNARY = (1, 3, 4, 5, 8, 9, 10, 14, 15)
PAPER_BINARY = (1, 2)
#: The operations of a problem file that names none: the paper's set with the geometry
#: operations (unary wrap, cos, sin; binary atan2, hypot) -- [choice] docs/methods/network_operator.md
#: "Choosing the operations"; registered systems keep the paper's set.  Not the signed square
#: (30 ssq): worse on the tuning half's medians -- [choice] docs/methods/network_operator.md "ssq".
FILE_UNARY = PAPER_UNARY + (29, 11, 12)
FILE_BINARY = PAPER_BINARY + (9, 10)
#: The authors' wider operation set (``--wide-ops``).
WIDE_UNARY, WIDE_BINARY = tuple(range(1, 29)), (1, 2, 3, 4)


@dataclass(frozen=True)
class GAConfig:
    """Sizes and rates of the variational GA."""

    # [choice] maxima: the dominance counts of a population of n laws take n^2 (2 m + 1)
    # bytes (150 MB at 5000 laws, 2 objectives); a generation's children are 4 crossovers
    population: int = setting(128, "individuals in the population", 4, 5_000)
    crossovers: int = setting(32, "crossover attempts per generation (4 children each)",
                              1, 10_000)
    lchr: int = setting(8, "variations per individual (0 = parameters of the basic law only)",
                        0, 256)
    epoch: int = setting(10, "generations between changes of the basic solution", 1, 1_000_000)
    p_mutation: float = setting(0.7, "probability that a child mutates", 0.0, 1.0)
    alpha: float = setting(0.4, "crossover probability (1 + alpha Lh) / (1 + Lh)", 0.0, 1e6)
    ksearch: int = setting(4, "tournament size for the first parent", 1, 1_000)
    elite_trim: int = setting(4, "Pareto members whose variation lists are trimmed per epoch",
                              0, 64)
    basis_rule: str = setting("target", "the epoch's new basis: 'target' (the best law by "
                              "the target) or 'compromise' (nearest the utopia point, the lab's "
                              "rule)", choices=("target", "compromise"))
    basis_q: float = setting(0.0, "probability that a child takes the basic solution's "
                                  "parameters instead of its parents' (a variation of the "
                                  "structure flown with the tuned parameters)", 0.0, 1.0)
    restart_epochs: int = setting(2, "epochs without a better law by the target (by "
                                     "stall_gain) after which the structure search restarts "
                                     "(restart_from; 0 = never)",
                                  0, 1_000_000)
    # [choice] islands after a 10 % stall: docs/methods/network_operator.md "islands"
    stall_gain: float = setting(0.1, "an epoch whose best law by the target beats the "
                                      "best at the last mark by less than this share counts "
                                      "as a stalled one (restart_epochs)", 0.0, 1.0)
    restart_from: str = setting("islands", "where a restart of a stalled structure search "
                                "starts: 'best' (new members around the best law) or "
                                "'islands' (a new population from the basic solution, and "
                                "back to the run's best law when that one stalls below it)",
                                choices=("best", "islands"))
    # [choice] where an island starts: docs/methods/network_operator.md "islands from varied
    # basic solutions"
    island_from: str = setting("varied", "where a new island starts (restart_from 'islands'): "
                               "'basic' (the tuned basic solution), 'varied' (the tuned basic "
                               "solution with island_variations random variations, drawn anew "
                               "each island) "
                               "or 'archive' (the stalled population's Pareto member of another "
                               "form farthest from the best law's matrix)",
                               choices=("basic", "varied", "archive"))
    island_variations: int = setting(2, "random variations of a 'varied' island's centre "
                                     "(0 = lchr)", 0, 256)
    equivalence_probes: int = setting(16, "input points on which a law equivalent to one "
                                          "flown before is recognised and not flown again "
                                          "(0 = off)", 0, 256)
    # [choice] off by default: docs/methods/network_operator.md "Function-preserving starts"
    morph: int = setting(0, "probe points on which a child of a new form takes constants that "
                            "match its parent's law (the constants its change touched, by "
                            "least squares; 0 = off)", 0, 256)
    # [choice] off by default: docs/methods/network_operator.md "Weighted arcs"
    weighted_arcs: float = setting(0.0, "probability that a random variation is a weighted "
                                        "arc (an added arc whose input is scaled by an unused "
                                        "constant, which starts at 0: the child starts as its "
                                        "parent; 0 = off)", 0.0, 1.0)
    arc_ops: int = setting(0, "a random variation that changes an arc's operation picks one "
                              "of the member's arcs (1), not any pair of nodes, where most "
                              "pairs have no arc and the variation does nothing (0: as drawn)",
                           0, 1)
    # [choice] off by default: docs/methods/network_operator.md "CMA-ES refinement of the
    # parameters" (the paragraph on credit)
    credit: float = setting(0.0, "share of random structure variations whose kind and "
                                 "operation are drawn by their credit (how often a child "
                                 "whose fresh variation changed its law entered the "
                                 "population, recent generations weighing most) instead of "
                                 "uniformly (0 = off: the draws as before the setting existed)",
                            0.0, 1.0)

    def __post_init__(self):
        check_settings(self, "ga.")
