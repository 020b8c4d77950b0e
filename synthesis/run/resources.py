"""What a run may take of the machine: the documented maxima and the memory check made before
anything is allocated.

Every size a user can give has a documented maximum (the settings dataclasses' limits, the
problem's in :mod:`synthesis.problems.limits`, the workers' :data:`MAX_WORKERS`); sizes
within their maxima can still add up, so :func:`check_memory` estimates what a run will hold
(the population and its dominance counts, the fingerprints of the flown laws, the evaluator's
cache, one law's recorded flights per worker) and compares it with the memory the machine has
available, before the first law is built or flown.  The estimates are upper bounds of the
structures' sizes, measured on this package's objects.
"""
from __future__ import annotations

from descent_fmus.synthesis.problems.limits import (MAX_STATES, MAX_STEPS, ResourceLimitError,
                                                    check_steps)

__all__ = ["MAX_WORKERS", "MAX_STATES", "MAX_STEPS", "ResourceLimitError", "available_memory",
           "memory_estimate", "check_memory"]

#: Most local worker processes (each loads the FMUs: ~150 MB with pythonfmu FMUs).
MAX_WORKERS = 256
#: Bytes per item of the run's structures [measured upper bounds]: a fingerprint in the set
#: of flown laws, an outcome in the cache, a GA member (per bit and per variation), one recorded
#: value of a flight (a float in a tuple in a list), a worker process with its FMUs loaded.
_FINGERPRINT, _OUTCOME, _BIT, _VARIATION, _MEMBER = 120, 1_500, 1, 80, 600
_RECORDED, _WORKER = 40, 150 * 2 ** 20


def available_memory() -> int | None:
    """Bytes of memory available to new allocations (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def memory_estimate(problem, workers: int) -> dict:
    """Bytes the run of ``problem`` (its recipe) holds at most, by structure."""
    from descent_fmus.synthesis.run.evaluation import CACHE_SIZE
    ga, budget = problem.ga, problem.budget
    basic = problem.basic()
    bits = len(basic.q) * (problem.q_bits[0] + problem.q_bits[1])
    member = _MEMBER + bits * _BIT + ga.lchr * _VARIATION
    m = len(problem.objective_names)
    steps = problem.wiring.stop_time / problem.wiring.step
    signals = len(problem.record) + len(problem.initial) + len(problem.wiring.to_controller) + \
        len(problem.wiring.to_plant) + 1
    flights = budget.flights or (ga.population + budget.generations * 4 * ga.crossovers)
    return {
        "population": (ga.population + 4 * ga.crossovers) * member,
        "dominance counts": ga.population ** 2 * (2 * m + 1),
        "flown laws": flights * _FINGERPRINT,
        "cache": min(flights, CACHE_SIZE) * _OUTCOME,
        "recorded flights": (workers * len(problem.initial_states) * steps * signals
                             * _RECORDED if problem.record or problem.initial else 0),
        "workers": (workers - 1) * _WORKER if workers > 1 else 0,
    }


def check_memory(problem, workers: int, available: int | None = None) -> dict:
    """:func:`memory_estimate`, checked against the machine's available memory (80 % of it);
    ResourceLimitError naming the largest structure and what to lower."""
    if workers > MAX_WORKERS:
        raise ResourceLimitError(f"workers: {workers} asked; the documented maximum is "
                                 f"{MAX_WORKERS}")
    if len(problem.initial_states) > MAX_STATES:
        raise ResourceLimitError(f"problem {problem.name}: {len(problem.initial_states)} "
                                 f"initial states; the documented maximum is {MAX_STATES}")
    check_steps(problem.wiring.stop_time, problem.wiring.step, f"problem {problem.name}")
    est = memory_estimate(problem, workers)
    available = available_memory() if available is None else available
    total = sum(est.values())
    if available is not None and total > 0.8 * available:
        worst = max(est, key=est.get)
        raise ResourceLimitError(
            f"problem {problem.name}: the run would hold about {total / 2 ** 30:.1f} GiB "
            f"({worst}: {est[worst] / 2 ** 30:.1f} GiB), more than the {available / 2 ** 30:.1f} "
            f"GiB this machine has available; lower the population, the flights or the "
            f"initial states")
    return est
