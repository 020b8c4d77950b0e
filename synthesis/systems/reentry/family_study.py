"""S1 guidance options over held-out sets of the model-error families, every flight through the
FMUs, each beside its physical limits.

For every family named (:mod:`.error_families`) :func:`family_study` draws its held-out set
(Latin hypercube, ``samples`` points, ``seed``; around the default scenario or ``base``),
flies every guidance option on it (the laws given -- a law with the on-board correction may
come with controller parameters, e.g. the re-planner ``{"replan": 1}`` --, the paper's basic
law, the NPC) with each sample's accelerometer errors simulated in the estimator, and puts
beside them

* the **oracle bound** per sample (the miss of the best constant control with the true
  parameters: no law misses less), and
* the **load oracle** per sample (the least peak load of a zero-miss 1 s program with the true
  parameters, :mod:`.load_oracle`), both cached by content.

The result has the form of :func:`.robust_study.robust_study`'s (one "scenario" per family),
so :func:`.robust_study.table_lines` and :func:`.robust_study.plot_robust_study` print and plot
it; the load oracle is one more row (its J1) and one more box.
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict
from pathlib import Path

import numpy as np

from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.systems.reentry.error_families import family, family_samples
from descent_fmus.synthesis.systems.reentry.laws import paper_basic_law
from descent_fmus.synthesis.systems.reentry.robust_study import (BASIC, NPC, ORACLE,
                                                                  _with_guidance, fly_law,
                                                                  fly_npc, stats)

__all__ = ["family_study", "LOAD_ORACLE", "oracle_stats", "FAMILY_SEED"]

#: Name of the load oracle's row.
LOAD_ORACLE = "load oracle (min J1, zero miss)"
#: Default seed of the families' held-out sets (the synthesis sets use other seeds).
FAMILY_SEED = 7


def oracle_stats(limits) -> dict:
    """The rows of the oracle bound and the load oracle (where computed)."""
    miss = np.array([r["miss"] for r in limits], float)
    row = {"miss_median": float(np.median(miss)), "miss_p90": float(np.percentile(miss, 90)),
           "miss_p95": float(np.percentile(miss, 95)), "miss_max": float(miss.max()),
           "within_1km": float(np.mean(miss < 1000.0)),
           "within_5km": float(np.mean(miss < 5000.0)),
           "exact": float(np.mean([r["exact"] for r in limits]))}
    out = {ORACLE: row}
    j1 = [r["J1_load"] for r in limits if "J1_load" in r]
    if j1:
        out[LOAD_ORACLE] = {"J1_median": float(np.median(j1)), "J1_max": float(np.max(j1)),
                            "computed": len(j1)}
    return out


def _kept_path(folder, stem: str, what) -> Path | None:
    """Where the flights named ``stem`` of the option and scenario ``what`` (JSON-able: the
    law's start values, its guidance parameters, the scenario) are kept in ``folder`` (None:
    not kept); another law under the same name gets another file."""
    if folder is None:
        return None
    key = hashlib.sha1(json.dumps(what, sort_keys=True, default=float).encode()).hexdigest()
    return Path(folder) / (re.sub(r"[^A-Za-z0-9.]+", "-", stem).strip("-") + f"-{key[:10]}.json")


def _kept(path: Path | None, fly) -> list:
    """The rows of ``fly()``, kept in ``path`` as JSON and read back from it when it exists
    (None: flown every time)."""
    if path is None:
        return fly()
    if not path.exists():
        from descent_fmus.synthesis.cli.common import json_safe
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(json_safe(fly())))
        tmp.replace(path)
    return json.loads(path.read_text())


def family_study(laws: dict, families, samples: int, seed: int, fmu_dir, npc: bool = True,
                 oracle: bool = True, load_oracle: int | None = None, basic: bool = True,
                 progress=None, base: ReentryParams = ReentryParams(),
                 flown: Path | None = None) -> dict:
    """Fly every option over each family's held-out set (module docstring).  ``laws`` maps a
    name to a law or to ``(law, controller parameters)``; ``load_oracle`` = the number of
    samples (from the first) whose load oracle is computed (None: all, 0: none); ``base`` the
    scenario the families are drawn around (default: the default scenario); ``flown`` a
    folder where each option's flights over each family's set are kept and read back on a
    second call (None: not kept).

    Returns ``{"samples", "seed", "families", "scenarios": {family: {"params", "sensing",
    "results", "stats", "oracle", "limits"}}}``."""
    from descent_fmus.synthesis.systems.reentry.load_oracle import set_limits
    fmu_dir = Path(fmu_dir)
    options = dict(laws)
    if basic:
        options.setdefault(BASIC, paper_basic_law())
    out = {"samples": samples, "seed": seed, "families": {}, "scenarios": {},
           "held_out_set": {"samples": samples, "seed": seed, "design": "latin hypercube"},
           "disjoint": True, "synthesis_set": {"samples": 0, "seed": None}}
    for name in families:
        fam = family(name)
        out["families"][name] = fam.description
        sset = family_samples(name, samples, seed, base)
        results = {}
        def kept(label, what):
            return _kept_path(flown, f"{name} {samples} {seed} {label}", [what, asdict(base)])
        for n, option in options.items():
            law, guidance = _with_guidance(option)
            results[n] = _kept(kept(n, [law.start_values(), guidance]),
                               lambda: fly_law(law, sset, fmu_dir, guidance=guidance))
            if progress is not None:
                progress(name, n)
        if npc:
            results[NPC] = _kept(kept(NPC, None), lambda: fly_npc(sset, fmu_dir))
        sc = {"params": [asdict(s.plant) for s in sset], "sensing": [s.sensing for s in sset],
              "results": results,
              "stats": {n: stats(rows) for n, rows in results.items()}}
        if oracle:
            n_load = samples if load_oracle is None else min(load_oracle, samples)
            limits = set_limits([s.plant for s in sset[:n_load]], load=True, base=base) + \
                set_limits([s.plant for s in sset[n_load:]], load=False, base=base)
            sc["limits"] = limits
            sc["oracle"] = [r["miss"] for r in limits]
            sc["stats"].update(oracle_stats(limits))
        out["scenarios"][name] = sc
    return out
