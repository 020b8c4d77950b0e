"""The settings of the genetic-programming baseline (:mod:`synthesis.methods.gp`), apart from it
so that the problem contract reads them without importing DEAP."""
from __future__ import annotations

from dataclasses import dataclass

from descent_fmus.synthesis.methods.settings import SettingError, check_settings, setting

__all__ = ["GPConfig"]


@dataclass(frozen=True)
class GPConfig:
    """The GP's settings (``synthesize --gp-population ...``, a problem file's ``[gp]``)."""

    population: int = setting(200, "GP individuals per generation (one tree per output each)",
                              2, 100_000)
    tournament: int = setting(3, "GP tournament size of the selection", 1, 1000)
    p_crossover: float = setting(0.5, "GP probability that a pair of offspring exchanges "
                                      "sub-trees (one output's trees, one-point crossover)",
                                 0.0, 1.0)
    p_mutation: float = setting(0.1, "GP probability that an offspring's tree (one output's) "
                                     "gets a new random sub-tree", 0.0, 1.0)
    max_depth: int = setting(17, "GP static depth limit of a tree (an offspring beyond it, or "
                                 "beyond the controller FMU's nodes and parameters, keeps a "
                                 "parent's tree)", 1, 90)
    init_depth: int = setting(2, "GP largest depth of the initial trees (ramped "
                                 "half-and-half from depth 1)", 1, 17)
    mutation_depth: int = setting(2, "GP largest depth of a mutation's new sub-tree", 0, 17)
    const_range: float = setting(1.0, "GP ephemeral constants uniform in [-X, X]", 1e-6, 1e6)

    def __post_init__(self):
        check_settings(self, "gp.")
        if self.init_depth > self.max_depth:
            raise SettingError("gp.init_depth", f"must be <= gp.max_depth = {self.max_depth}, "
                                                f"got {self.init_depth}")
