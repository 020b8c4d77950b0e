"""A synthesis run: the variational GA + the FMU evaluator, with checkpoints, outputs and export.

``descent-fmus synthesize NAME --out DIR`` (or ``--problem FILE.toml``) drives
:func:`run_synthesis`.  DIR receives

* ``run.json``        -- what was asked (problem, source, budget); a different run refuses DIR;
* ``checkpoint.json`` -- the GA state after every generation (``--resume`` continues from it);
* ``pareto.csv``, ``pareto.json``, ``pareto.png`` -- the Pareto set (one law per row);
* ``summary.json``    -- the report (counts, rates, the problem's own report fields);
* ``laws/<k>/``       -- per Pareto law: ``law.json``, the controller FMU carrying the law as
  defaults, the closed-loop container FMU and its SSP file.
"""
from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.evaluator import Evaluator
from descent_fmus.synthesis.methods.ga import GrayCodec, StructureCodec, VariationalGA
from descent_fmus.synthesis.methods.network_operator import NetworkOperator
from descent_fmus.synthesis.problem import Budget, SynthesisProblem

__all__ = ["RunDirError", "run_synthesis", "make_ga", "export_law", "plot_front", "WIDE_UNARY",
           "WIDE_BINARY"]

RUN_FILE, CHECKPOINT = "run.json", "checkpoint.json"
#: The authors' wider operation set (``--wide-ops``).
WIDE_UNARY, WIDE_BINARY = tuple(range(1, 29)), (1, 2, 3, 4)


class RunDirError(ValueError):
    """The output directory holds a different run (or no run to resume)."""


def _write_json(path: Path, data) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)        # atomic: a killed run never leaves a half-written file


def make_ga(problem: SynthesisProblem, budget: Budget, wide_ops: bool = False) -> VariationalGA:
    """The GA for a problem: basic law, operation sets, Gray coding of q, seeded generator."""
    basic = problem.basic_law
    ib, fb, lo, hi = problem.q_bits
    unary = WIDE_UNARY if wide_ops else problem.unary
    binary = WIDE_BINARY if wide_ops else problem.binary
    structure = StructureCodec(basic.size, basic.nx + len(basic.q), unary, binary)

    def decode(psi, q):
        return replace_law(basic, psi, q)

    return VariationalGA(GrayCodec(len(basic.q), ib, fb, lo, hi), basic.q,
                         np.random.default_rng(budget.seed), budget.ga_config(), structure,
                         basic.psi, decode)


def replace_law(basic: NetworkOperator, psi, q) -> NetworkOperator:
    """``basic`` with another matrix and parameters (inputs, outputs, bounds, scaling kept)."""
    return NetworkOperator(psi, basic.nx, q, basic.outputs, basic.bounds, basic.input_names,
                           basic.input_scale, basic.input_offset)


def _run_spec(problem: SynthesisProblem, budget: Budget, wide_ops: bool) -> dict:
    return {"problem": problem.name, "source": problem.source, "seed": budget.seed,
            "ga": asdict(budget.ga_config()), "wide_ops": wide_ops,
            "generations": budget.generations}


def _same_run(a: dict, b: dict) -> bool:
    keys = ("problem", "source", "seed", "ga", "wide_ops")
    return all(a.get(k) == b.get(k) for k in keys)


def run_synthesis(problem: SynthesisProblem, out: Path, fmu_dir: Path,
                  budget: Budget | None = None, workers: int = 1,
                  scheduler: str | None = None, resume: bool = False, wide_ops: bool = False,
                  progress: bool = True, export: bool = True, stop_after: int | None = None,
                  reference: bool = True) -> dict:
    """Run (or resume) a synthesis; return the summary dict (also written to DIR).

    Parameters
    ----------
    problem : SynthesisProblem
    out : path-like
        Run folder (must be empty or absent, or hold this run with ``resume``).
    fmu_dir : path-like
        Folder of the built FMUs.
    budget : Budget, optional
        Default: the problem's.
    workers, scheduler :
        Local worker processes, or the address of a Dask scheduler.
    reference : bool
        Let the problem's report compute an expensive reference (e.g. the reentry bound).
    stop_after : int, optional
        End after that many generations of this call (the checkpoint tests' interruption).
    """
    budget = budget or problem.budget
    out = Path(out)
    spec = _run_spec(problem, budget, wide_ops)
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
    evaluator = Evaluator(problem, fmu_dir, workers=workers, scheduler=scheduler)
    out.mkdir(parents=True, exist_ok=True)
    ga = make_ga(problem, budget, wide_ops)
    if resume:
        ga.load_state(json.loads(ckpt.read_text()))
    else:
        _write_json(run_file, spec)

    generations = budget.generations
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
            post.update(problem.report.headline(front))
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
        return {"interrupted": True, "generation": ga.generation}
    finally:
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - t0
    summary = _write_results(problem, ga, evaluator, out, fmu_dir, export, reference)
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
    """A law as FMUs: controller FMU with the law as defaults, closed-loop FMU, SSP.

    The plant parameters the problem sets per initial state stay parameters of the closed-loop
    FMU, so a law of a problem with several initial states can be flown from each of them.
    """
    from descent_fmus.synthesis.export import closed_loop_fmu, with_defaults, write_ssp
    dest.mkdir(parents=True, exist_ok=True)
    law.save(dest / "law.json")
    w = problem.wiring
    plant_fmu, ctrl_fmu = problem.fmu_paths(fmu_dir)
    ctrl = with_defaults(ctrl_fmu, dest / ctrl_fmu.name, law.start_values(),
                         description=(description or "network-operator law") + ": "
                         + law.formula(6))
    wl = replace(w, description=(description or w.description) + "; law " + law.formula(6))
    names = list(dict.fromkeys(k for s in problem.initial_states for k in s))
    plant_params = tuple((n, "plant", n) for n in names)
    cl = closed_loop_fmu(wl, plant_fmu, ctrl, dest / f"{w.name}.fmu", parameters=plant_params)
    ssp = write_ssp(wl, plant_fmu, ctrl, dest / f"{w.name}.ssp")
    return {"controller_fmu": str(ctrl), "closed_loop_fmu": str(cl), "ssp": str(ssp)}


def _rows(problem, front, extras) -> list:
    rows = []
    for k, (law, f, _) in enumerate(front):
        row = {"k": k}
        row.update({n: float(v) for n, v in zip(problem.objective_names, f)})
        row.update({n: v for n, v in extras[k].items() if isinstance(v, (int, float, bool))})
        row["formula"] = law.formula(6)
        rows.append(row)
    return rows


def _write_results(problem, ga, evaluator, out: Path, fmu_dir, export: bool,
                   reference: bool) -> dict:
    front = ga.pareto()
    laws = [law for law, _, _ in front]
    _, extras = evaluator.evaluate(laws)
    rows = _rows(problem, front, extras)
    fields = list(dict.fromkeys(key for r in rows for key in r))
    with open(out / "pareto.csv", "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=fields)
        wr.writeheader()
        wr.writerows(rows)

    def pareto_json():
        _write_json(out / "pareto.json", [dict(r, law=law.to_dict(),
                                               variations=[list(v) for v in var])
                                          for r, (law, _, var) in zip(rows, front)])

    pareto_json()
    fb, _ = evaluator.evaluate([problem.basic_law])
    names = problem.objective_names
    summary = {"problem": problem.name, "pareto_size": len(rows),
               "basic_law": dict(zip(names, map(float, fb[0])))}
    summary.update(problem.report.summary(rows, out, reference))
    plot_front(problem, rows, summary, out / "pareto.png")
    if export:
        for r, law in zip(rows, laws):
            r.update(export_law(problem, law, fmu_dir, out / "laws" / str(r["k"]),
                                description=f"{problem.name} Pareto law {r['k']}"))
        pareto_json()
    summary["pareto"] = rows
    return summary


def plot_front(problem, rows, summary, path: Path) -> None:
    """pareto.png: the front, the basic law and (if the report gives one) a reference value of
    objective 1 (``summary["reference"] = {"value": ..., "label": ...}``)."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure
    names = problem.objective_names
    if len(names) != 2:
        return
    f1 = np.array([r[names[0]] for r in rows])
    f2 = np.array([r[names[1]] for r in rows])
    ok = f2 < problem.penalty[1] / 4
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.plot(f1[ok], f2[ok], "o", ms=4, label="Pareto set (synthesised laws)")
    b = summary["basic_law"]
    ax.plot(b[names[0]], b[names[1]], "s", color="C3", label="basic law (start)")
    ref = summary.get("reference")
    if ref:
        ax.axvline(ref["value"], color="k", ls="--", lw=1,
                   label=f"{ref['label']} {names[0]} = {ref['value']:.4g}")
    ax.set_xlabel(problem.labels[0])
    ax.set_ylabel(problem.labels[1])
    ax.set_yscale("symlog", linthresh=max(1e-9, float(np.min(np.abs(f2[ok])))
                  if ok.any() and np.min(np.abs(f2[ok])) > 0 else 1.0))
    ax.legend()
    ax.set_title(f"{problem.name}: Pareto front ({len(rows)} laws)")
    save_figure(fig, path, [ax], dpi=110)
