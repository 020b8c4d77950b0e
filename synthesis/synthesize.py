"""A synthesis run: the variational GA + the FMU evaluator, with checkpoints, outputs and export.

``descent-fmus synthesize NAME --out DIR`` drives :func:`run_synthesis`.  DIR receives

* ``run.json``        -- what was asked (problem, seed, sizes); a different run refuses DIR;
* ``checkpoint.json`` -- the GA state after every generation (``--resume`` continues from it);
* ``pareto.csv``, ``pareto.json``, ``pareto.png`` -- the Pareto set (one law per row);
* ``laws/<k>/``       -- per Pareto law: ``law.json``, the controller FMU carrying the law as
  defaults, the closed-loop container FMU and its SSP file.
"""
from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from synthesis.evaluator import Evaluator, SynthesisProblem, get_problem
from synthesis.ga import GAConfig, GrayCodec, StructureCodec, VariationalGA
from synthesis.network_operator import NetworkOperator

__all__ = ["RunDirError", "run_synthesis", "make_ga", "export_law"]

RUN_FILE, CHECKPOINT = "run.json", "checkpoint.json"


class RunDirError(ValueError):
    """The output directory holds a different run (or no run to resume)."""


def _write_json(path: Path, data) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)        # atomic: a killed run never leaves a half-written file


def make_ga(problem: SynthesisProblem, config: GAConfig, seed: int, wide_ops: bool = False
            ) -> VariationalGA:
    """The GA for a problem: basic law, operation sets, Gray coding of q."""
    basic = problem.basic_law()
    ib, fb, lo, hi = problem.q_bits
    unary = tuple(range(1, 29)) if wide_ops else problem.unary
    binary = (1, 2, 3, 4) if wide_ops else problem.binary
    structure = StructureCodec(basic.size, basic.nx + len(basic.q), unary, binary)

    def decode(psi, q):
        return NetworkOperator(psi, basic.nx, q, basic.outputs, basic.bounds, basic.input_names)

    return VariationalGA(GrayCodec(len(basic.q), ib, fb, lo, hi), basic.q,
                         np.random.default_rng(seed), config, structure, basic.psi, decode)


def _run_spec(problem, config, seed, generations, wide_ops) -> dict:
    return {"problem": problem.name, "seed": seed, "ga": asdict(config),
            "wide_ops": wide_ops, "generations": generations}


def _same_run(a: dict, b: dict) -> bool:
    keys = ("problem", "seed", "ga", "wide_ops")
    return all(a.get(k) == b.get(k) for k in keys)


def run_synthesis(problem_name: str, out: Path, fmu_dir: Path, config: GAConfig,
                  generations: int, seed: int = 1, workers: int = 1,
                  scheduler: str | None = None, resume: bool = False, wide_ops: bool = False,
                  progress: bool = True, export: bool = True, stop_after: int | None = None,
                  reference_j1: float | None = None, bound: bool = True) -> dict:
    """Run (or resume) a synthesis; return the summary dict (also written to DIR).

    ``reference_j1`` is the bound the report compares with (reentry: the open-loop optimum);
    if None and ``bound`` is true, the problem computes it (``defaults["reference"]``).
    ``stop_after`` ends the process after that many generations of this call (used by the
    checkpoint tests to simulate an interruption).
    """
    problem = get_problem(problem_name)
    out = Path(out)
    spec = _run_spec(problem, config, seed, generations, wide_ops)
    run_file, ckpt = out / RUN_FILE, out / CHECKPOINT
    if resume:
        if not run_file.exists() or not ckpt.exists():
            raise RunDirError(f"{out} holds no run to resume (no {RUN_FILE}/{CHECKPOINT})")
        old = json.loads(run_file.read_text())
        if not _same_run(old, spec):
            raise RunDirError(f"{out} holds a different run ({old.get('problem')}, seed "
                              f"{old.get('seed')}, {old.get('ga')}); resume it with the same "
                              f"options or choose another --out")
    elif out.exists() and any(out.iterdir()):
        if run_file.exists():
            raise RunDirError(f"{out} already holds a run: continue it with --resume or choose "
                              f"another --out (nothing was overwritten)")
        raise RunDirError(f"{out} is not empty and holds no descent-fmus run; choose another "
                          f"--out (nothing was overwritten)")
    out.mkdir(parents=True, exist_ok=True)
    ga = make_ga(problem, config, seed, wide_ops)
    if resume:
        ga.load_state(json.loads(ckpt.read_text()))
    else:
        _write_json(run_file, spec)

    evaluator = Evaluator(problem, fmu_dir, workers=workers, scheduler=scheduler)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=generations, initial=min(ga.generation, generations), unit="gen",
                   desc=f"synthesize {problem.name}", dynamic_ncols=True)
    t0, ev0 = time.perf_counter(), evaluator.simulated
    start_gen = ga.generation
    names = problem.objective_names

    def callback(g):
        _write_json(ckpt, g.state())
        if bar is not None:
            bar.n = min(g.generation, generations)
            front = g.F[g.lh == 0]
            rate = (evaluator.simulated - ev0) / max(time.perf_counter() - t0, 1e-9)
            post = {"evals/s": f"{rate:.0f}", "front": len(front)}
            for k, n in enumerate(names):
                post[f"min {n}"] = f"{front[:, k].min():.4g}"
            head = problem.defaults.get("headline")
            if head:
                post.update(head(front))
            bar.set_postfix(post, refresh=False)
            bar.refresh()
        if stop_after is not None and g.generation - start_gen >= stop_after \
                and g._pending is None:
            raise _Interrupt

    try:
        remaining = max(0, generations - ga.generation)
        if not ga.pop:
            remaining = generations
        ga.run(lambda cands: evaluator.evaluate(cands)[0], remaining, callback)
    except _Interrupt:
        evaluator.close()
        if bar is not None:
            bar.close()
        return {"interrupted": True, "generation": ga.generation}
    finally:
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - t0
    if reference_j1 is None and bound and problem.defaults.get("reference"):
        # the problem's bound for the report (reentry: the best open-loop program)
        reference_j1 = problem.defaults["reference"](out)
    summary = _write_results(problem, ga, evaluator, out, fmu_dir, export, reference_j1)
    summary.update({"seconds": elapsed, "evaluations": ga.evaluations,
                    "simulated": evaluator.simulated, "failures": evaluator.failures,
                    "evaluations_per_second": (evaluator.simulated - ev0) / max(elapsed, 1e-9),
                    "generations": ga.generation, "out": str(out)})
    evaluator.close()
    _write_json(out / "summary.json", summary)
    return summary


class _Interrupt(Exception):
    pass


def export_law(problem: SynthesisProblem, law: NetworkOperator, fmu_dir: Path, dest: Path,
               description: str = "") -> dict:
    """A law as FMUs: controller FMU with the law as defaults, closed-loop FMU, SSP."""
    from dataclasses import replace

    from synthesis.export import closed_loop_fmu, with_defaults, write_ssp
    dest.mkdir(parents=True, exist_ok=True)
    law.save(dest / "law.json")
    w = problem.wiring
    ctrl = with_defaults(Path(fmu_dir) / problem.controller_fmu, dest / problem.controller_fmu,
                         law.start_values(),
                         description=(description or "network-operator law") + ": "
                         + law.formula(6))
    wl = replace(w, description=(description or w.description) + "; law " + law.formula(6))
    # the plant parameters the registered closed loop exposes (initial state, ...) stay settable,
    # so a law of a problem with several initial states can be flown from each of them
    from synthesis import scenarios
    spec = scenarios.CLOSED_LOOPS.get(w.name)
    plant_params = tuple(p for p in spec.parameters if p[1] == "plant") if spec else ()
    cl = closed_loop_fmu(wl, Path(fmu_dir) / problem.plant_fmu, ctrl, dest / f"{w.name}.fmu",
                         parameters=plant_params)
    ssp = write_ssp(wl, Path(fmu_dir) / problem.plant_fmu, ctrl, dest / f"{w.name}.ssp")
    return {"controller_fmu": str(ctrl), "closed_loop_fmu": str(cl), "ssp": str(ssp)}


def _write_results(problem, ga, evaluator, out: Path, fmu_dir, export: bool,
                   reference_j1) -> dict:
    front = ga.pareto()
    laws = [law for law, _, _ in front]
    F, extras = evaluator.evaluate(laws)
    names = problem.objective_names
    rows = []
    for k, (law, f, var) in enumerate(front):
        row = {"k": k}
        row.update({n: float(v) for n, v in zip(names, f)})
        row.update({n: v for n, v in extras[k].items() if isinstance(v, (int, float, bool))})
        row["formula"] = law.formula(6)
        rows.append(row)
    fields = list(dict.fromkeys(key for r in rows for key in r))
    with open(out / "pareto.csv", "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=fields)
        wr.writeheader()
        wr.writerows(rows)
    _write_json(out / "pareto.json", [dict(r, law=law.to_dict(), variations=[list(v) for v in var])
                                      for r, (law, _, var) in zip(rows, front)])
    basic = problem.basic_law()
    fb, _ = evaluator.evaluate([basic])
    summary = {"problem": problem.name, "pareto_size": len(rows),
               "basic_law": dict(zip(names, map(float, fb[0])))}
    head = problem.defaults.get("summary")
    if head:
        summary.update(head(rows, reference_j1))
    plot_front(problem, rows, summary, out / "pareto.png", reference_j1)
    if export:
        for r, law in zip(rows, laws):
            r.update(export_law(problem, law, fmu_dir, out / "laws" / str(r["k"]),
                                description=f"{problem.name} Pareto law {r['k']}"))
        _write_json(out / "pareto.json", [dict(r, law=law.to_dict(),
                                               variations=[list(v) for v in var])
                                          for r, (law, _, var) in zip(rows, front)])
    summary["pareto"] = rows
    return summary


def plot_front(problem, rows, summary, path: Path, reference_j1) -> None:
    """pareto.png: the front, the basic law and (if known) the bound of objective 1."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = problem.objective_names
    f1 = np.array([r[names[0]] for r in rows])
    f2 = np.array([r[names[1]] for r in rows])
    ok = f2 < problem.penalty[1] / 4
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.plot(f1[ok], f2[ok], "o", ms=4, label="Pareto set (synthesised laws)")
    b = summary["basic_law"]
    ax.plot(b[names[0]], b[names[1]], "s", color="C3", label="basic law (start)")
    if reference_j1:
        ax.axvline(reference_j1, color="k", ls="--", lw=1,
                   label=f"open-loop optimum {names[0]} = {reference_j1:.3f}")
    ax.set_xlabel(problem.defaults.get("labels", names)[0])
    ax.set_ylabel(problem.defaults.get("labels", names)[1])
    ax.set_yscale("symlog", linthresh=100.0)
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(f"{problem.name}: Pareto front ({len(rows)} laws)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
