"""A synthesis run: the variational GA + the FMU evaluator, with checkpoints, outputs and export.

``descent-fmus synthesize NAME --out DIR`` (or ``--problem FILE.toml``) drives
:func:`run_synthesis`.  DIR receives

* ``run.json``        -- what was asked (problem, source, budget); a different run refuses DIR;
* ``checkpoint.json`` -- the GA state after every generation (``--resume`` continues from it);
* ``pareto.csv``, ``pareto.json``, ``pareto.png`` -- the Pareto set (one law per row);
* ``summary.json``    -- the report (counts, rates, the problem's own report fields);
* ``laws/<k>/``       -- per Pareto law (:class:`synthesis.fmi.law_files.LawExport`): ``law.json``
  (with the readable form), ``law.h``/``law.c`` and the law FMU (native C where a compiler
  exists), and when asked the closed-loop container FMU and its SSP file.
"""
from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.run.evaluation import Evaluator
from descent_fmus.synthesis.fmi.law_files import LawExport, choose_law_fmu, readable_text
from descent_fmus.synthesis.methods.ga import GAConfig, GrayCodec, StructureCodec, VariationalGA
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.problems.contract import Budget, SynthesisProblem
from descent_fmus.synthesis.run.guard import check_export_space, guarded

__all__ = ["RunDirError", "run_synthesis", "make_ga", "export_law", "plot_front", "WIDE_UNARY",
           "WIDE_BINARY"]

RUN_FILE, CHECKPOINT = "run.json", "checkpoint.json"
#: The method of ``synthesize``: the network operator (variational GA) by default.
NETWORK_OPERATOR = "network-operator"
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
    basic = problem.basic()
    ib, fb, lo, hi = problem.q_bits
    unary = WIDE_UNARY if wide_ops else problem.unary
    binary = WIDE_BINARY if wide_ops else problem.binary
    structure = StructureCodec(basic.size, basic.nx + len(basic.q), unary, binary)

    def decode(psi, q):
        return replace_law(basic, psi, q)

    return VariationalGA(GrayCodec(len(basic.q), ib, fb, lo, hi), basic.q,
                         np.random.default_rng(budget.seed), budget.ga_config(), structure,
                         basic.psi, decode,
                         target=problem.target if (budget.refine_evals or budget.refine_basis
                                                   or budget.basis_rule == "target")
                         else None)


def replace_law(basic: NetworkOperator, psi, q) -> NetworkOperator:
    """``basic`` with another matrix and parameters (inputs, outputs, bounds, scaling kept)."""
    return NetworkOperator(psi, basic.nx, q, basic.outputs, basic.bounds, basic.input_names,
                           basic.input_scale, basic.input_offset)


def _run_spec(problem: SynthesisProblem, budget: Budget, wide_ops: bool,
              method: str = NETWORK_OPERATOR) -> dict:
    spec = {"problem": problem.name, "source": problem.source, "seed": budget.seed,
            "ga": asdict(budget.ga_config()), "wide_ops": wide_ops,
            "generations": budget.generations}
    if method != NETWORK_OPERATOR:           # a fixed-structure search: no GA settings
        spec.update(method=method, flights=budget.flights, ga=None, generations=None)
    return spec


def _same_run(a: dict, b: dict) -> bool:
    keys = ("problem", "source", "seed", "wide_ops", "method")
    return all(a.get(k) == b.get(k) for k in keys) and _ga_spec(a) == _ga_spec(b)


def _ga_spec(spec: dict):
    """The GA settings of a run spec, fields a run written before they existed at their
    defaults."""
    ga = spec.get("ga")
    return None if ga is None else {**asdict(GAConfig()), **ga}



def methods(problem: SynthesisProblem) -> list:
    """The methods ``synthesize`` can run on ``problem``: the network operator and one
    fixed-structure CMA-ES policy search per baseline structure (``cma-<name>``)."""
    return [NETWORK_OPERATOR] + [f"cma-{n}" for n in (problem.baselines() if problem.baselines
                                                      else {})]


@guarded        # signals, systematic failures, full disks: synthesis/run/guard.py
def run_synthesis(problem: SynthesisProblem, out: Path, fmu_dir: Path,
                  budget: Budget | None = None, workers: int = 1,
                  scheduler: str | None = None, resume: bool = False, wide_ops: bool = False,
                  progress: bool = True, export=True, stop_after: int | None = None,
                  reference: bool = True, method: str = NETWORK_OPERATOR) -> dict:
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
    export : bool or LawExport
        What to write per Pareto law: True = everything (law files, law FMU, closed-loop FMU and
        SSP), False = nothing, or a :class:`~synthesis.fmi.law_files.LawExport`.
    reference : bool
        Let the problem's report compute an expensive reference (e.g. the reentry bound).
    stop_after : int, optional
        End after that many generations of this call (the checkpoint tests' interruption).
    method : str
        ``"network-operator"`` (the variational GA) or ``"cma-<baseline>"``: CMA-ES over the
        parameters of one of the problem's fixed baseline structures for ``budget.flights``
        evaluations (:func:`methods` lists them).
    """
    budget = budget or problem.budget
    out = Path(out)
    if method not in methods(problem):
        raise ValueError(f"unknown method {method!r} for problem {problem.name}; available: "
                         f"{', '.join(methods(problem))}")
    if method != NETWORK_OPERATOR and (problem.target is None or budget.flights < 1):
        raise ValueError(f"method {method} needs the problem's target and a flight budget "
                         f"(flights >= 1)")
    spec = _run_spec(problem, budget, wide_ops, method)
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
    evaluator = Evaluator(problem, fmu_dir, workers=workers, scheduler=scheduler,
                          fail_loudly=True)
    out.mkdir(parents=True, exist_ok=True)
    if method != NETWORK_OPERATOR:
        if not resume:
            _write_json(run_file, spec)
        return _run_policy_search(problem, method, budget, evaluator, out, fmu_dir, resume,
                                  progress, export, reference, stop_after)
    ga = make_ga(problem, budget, wide_ops)
    if resume:
        ga.load_state(json.loads(ckpt.read_text()))
    else:
        _write_json(run_file, spec)

    generations = budget.generations
    bar = None
    if progress:
        from tqdm import tqdm
        if budget.flights:       # the run ends when the flights are spent: count flights
            done = json.loads(ckpt.read_text()).get("simulated", 0) if resume else 0
            bar = tqdm(total=budget.flights, initial=min(done, budget.flights), unit="flight",
                       desc=f"synthesize {problem.name}", dynamic_ncols=True)
        else:
            bar = tqdm(total=generations, initial=min(ga.generation, generations), unit="gen",
                       desc=f"synthesize {problem.name}", dynamic_ncols=True)
    t0, ev0 = time.perf_counter(), evaluator.simulated
    start_gen = ga.generation
    names = problem.objective_names

    old_state = json.loads(ckpt.read_text()) if resume else {}
    curve = list(old_state.get("curve", []))
    sim0 = old_state.get("simulated", 0)       # flights of the run before this call

    def callback(g):
        flights = sim0 + evaluator.simulated
        if problem.target is not None and g.archive:
            k = problem.target.best([a[2] for a in g.archive])
            if k is not None:
                curve.append((flights, float(g.archive[k][2][problem.target.objective])))
        _write_json(ckpt, dict(g.state(), curve=curve, simulated=flights))
        if bar is not None:
            bar.n = (min(flights, budget.flights) if budget.flights
                     else min(g.generation, generations))
            post_gen = {"gen": g.generation}
            front = g.F[g.lh == 0]
            rate = (evaluator.simulated - ev0) / max(time.perf_counter() - t0, 1e-9)
            post = dict(post_gen, **{"evals/s": f"{rate:.0f}", "front": len(front)})
            for k, n in enumerate(names):
                post[f"min {n}"] = f"{front[:, k].min():.4g}"
            # the best so far: the run's archive (the population misses the refinements'
            # candidates until a refinement ends)
            best = np.array([a[2] for a in g.archive]) if g.archive else front
            post.update(problem.report.headline(best))
            bar.set_postfix(post, refresh=False)
            bar.refresh()
        if stop_after is not None and g.generation - start_gen >= stop_after \
                and g._pending is None:
            raise _Interrupt
        if budget.flights and flights >= budget.flights and g._pending is None:
            raise _FlightsSpent      # the same flight budget as the cma-* methods

    try:
        remaining = max(0, generations - ga.generation)
        if not ga.pop:
            remaining = generations
        ga.run(lambda cands: evaluator.evaluate(cands)[0], remaining, callback)
    except _Interrupt:
        evaluator.close()
        return {"interrupted": True, "generation": ga.generation}
    except _FlightsSpent:
        pass
    finally:
        if bar is not None:
            bar.close()
    return _finish(problem, ga, evaluator, out, fmu_dir, export, reference, t0, ev0, sim0,
                   evaluations=ga.evaluations, generations=ga.generation, method=method,
                   curve=curve)


def _finish(problem, result, evaluator, out, fmu_dir, export, reference, t0, ev0, sim0,
            **fields) -> dict:
    """Write the results of a run (``result.pareto()``) and its summary; close the evaluator."""
    elapsed = time.perf_counter() - t0
    summary = _write_results(problem, result, evaluator, out, fmu_dir, export, reference)
    summary.update({"seconds": elapsed, "simulated": evaluator.simulated,
                    "flights": sim0 + evaluator.simulated, "failures": evaluator.failures,
                    "first_failure": evaluator.first_error,
                    "evaluations_per_second": (evaluator.simulated - ev0) / max(elapsed, 1e-9),
                    "out": str(out)}, **fields)
    evaluator.close()
    _write_json(out / "summary.json", summary)
    return summary


class _Interrupt(Exception):
    pass


class _FlightsSpent(Exception):
    pass


class _Archive:
    """Non-dominated laws of a fixed-structure run (the result, as the GA's archive)."""

    def __init__(self, cap: int = 200):
        self.items, self.cap = [], cap

    def add(self, law, f) -> None:
        from descent_fmus.synthesis.methods.pareto import crowding_distance
        f = np.asarray(f, float)
        if any(np.all(g <= f) for _, g in self.items):
            return
        keep = [(lw, g) for lw, g in self.items if not (np.all(f <= g) and np.any(f < g))]
        keep.append((law, f))
        if len(keep) > self.cap:
            del keep[int(np.argmin(crowding_distance(np.array([g for _, g in keep]))))]
        self.items = keep

    def pareto(self) -> list:
        return [(law, f.copy(), []) for law, f in sorted(self.items, key=lambda a: tuple(a[1]))]

    def state(self) -> list:
        return [{"law": law.to_dict(), "f": f.tolist()} for law, f in self.items]

    def load(self, st) -> "_Archive":
        self.items = [(NetworkOperator.from_dict(a["law"]), np.array(a["f"], float)) for a in st]
        return self


def _run_policy_search(problem, method, budget, evaluator, out, fmu_dir, resume, progress,
                       export, reference, stop_after):
    """``--method cma-<baseline>``: CMA-ES over the parameters of a fixed structure, every
    candidate flown by the same evaluator; results written as for the network operator."""
    from descent_fmus.synthesis.methods.baselines import PolicySearch
    structure = problem.baselines()[method[len("cma-"):]]
    search = PolicySearch(structure, problem.target, seed=budget.seed)
    archive, curve, ckpt, sim0 = _Archive(), [], out / CHECKPOINT, 0
    if resume:
        st = json.loads(ckpt.read_text())
        search.load_state(st["search"])
        archive.load(st["archive"])
        curve, sim0 = list(st["curve"]), st["simulated"]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=budget.flights, initial=min(search.evaluations, budget.flights),
                   unit="eval", desc=f"{method} {problem.name}", dynamic_ncols=True)
    t0, ev0, start = time.perf_counter(), evaluator.simulated, search.generations

    def evaluate(laws):
        F = evaluator.evaluate(laws)[0]
        for law, f in zip(laws, F):
            archive.add(law, f)
        return F

    try:
        while sim0 + evaluator.simulated < budget.flights:
            search.tell(evaluate(search.ask()))
            flights = sim0 + evaluator.simulated
            if search.best_f is not None:
                curve.append((flights, float(search.best_f[problem.target.objective])))
            _write_json(ckpt, {"search": search.state(), "archive": archive.state(),
                               "curve": curve, "simulated": flights})
            if bar is not None:
                bar.n = min(flights, budget.flights)
                bar.set_postfix({"sigma": f"{search.sigma:.3g}", "restarts": search.restarts,
                                 **problem.report.headline(np.array([f for _, f in
                                                                     archive.items]))},
                                refresh=False)
                bar.refresh()
            if stop_after is not None and search.generations - start >= stop_after:
                evaluator.close()
                return {"interrupted": True, "evaluations": search.evaluations}
    finally:
        if bar is not None:
            bar.close()
    return _finish(problem, archive, evaluator, out, fmu_dir, export, reference, t0, ev0, sim0,
                   evaluations=search.evaluations, generations=search.generations,
                   restarts=search.restarts, method=method, curve=curve)


def export_law(problem: SynthesisProblem, law: NetworkOperator, fmu_dir: Path, dest: Path,
               description: str = "", law_fmu: str = "auto", closed_loop: bool = True,
               identifier: str | None = None, extra: dict | None = None) -> dict:
    """A law as files (:func:`synthesis.fmi.law_files.export_law_files`): ``law.json`` with its
    readable form, ``law.h``/``law.c``, the law FMU (native where a C compiler exists, else the
    pythonfmu controller with the law as defaults) and, with ``closed_loop``, the closed-loop
    FMU and SSP around that law FMU.

    The plant parameters the problem sets per initial state stay parameters of the closed-loop
    FMU, so a law of a problem with several initial states can be flown from each of them.
    """
    from descent_fmus.synthesis.fmi.law_files import export_law_files
    out = export_law_files(law, dest, law_fmu=law_fmu, fmu_dir=fmu_dir, identifier=identifier,
                           description=description, problem=problem, closed_loop=closed_loop,
                           extra=dict({"problem": problem.name}, **(extra or {})))
    out.pop("note")
    return out


def _rows(problem, front, extras) -> list:
    rows = []
    for k, (law, f, _) in enumerate(front):
        row = {"k": k}
        row.update({n: float(v) for n, v in zip(problem.objective_names, f)})
        row.update({n: v for n, v in extras[k].items() if isinstance(v, (int, float, bool))})
        row["formula"] = law.formula(6)
        row["readable"] = readable_text(law)
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
    fb, _ = evaluator.evaluate([problem.basic()])
    names = problem.objective_names
    summary = {"problem": problem.name, "pareto_size": len(rows),
               "basic_law": dict(zip(names, map(float, fb[0])))}
    summary.update(problem.report.summary(rows, out, reference))
    plot_front(problem, rows, summary, out / "pareto.png")
    what = LawExport.of(export)
    if what is not None:
        kind, note = choose_law_fmu(what.law_fmu)
        check_export_space(out, problem, fmu_dir, len(rows), what.closed_loops, law_fmu=kind)
        summary.update(law_fmus=kind, **({"law_fmu_note": note} if note else {}))
        stem = problem.wiring.name.removesuffix("ClosedLoop")
        for r, law in zip(rows, laws):
            r.update(export_law(problem, law, fmu_dir, out / "laws" / str(r["k"]),
                                description=f"{problem.name} Pareto law {r['k']}",
                                law_fmu=kind, closed_loop=what.closed_loops,
                                identifier=f"{stem}Law{r['k']}",
                                extra={"k": r["k"], "objectives": {
                                    n: r[n] for n in problem.objective_names}}))
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
    if ok.any() and np.min(f2[ok]) >= 0 and b[names[1]] >= 0:
        ax.set_ylim(bottom=0)            # a non-negative objective: no empty negative decades
        ax.set_ylim(top=10 ** (np.log10(max(np.max(f2[ok]), b[names[1]], 1e-9)) + 0.5))
    ax.legend(loc="center right")
    ax.set_title(f"{problem.name}: Pareto front ({len(rows)} laws)")
    save_figure(fig, path, [ax], dpi=110)
