"""What a finished synthesis run writes: the Pareto set, the summary, the figure, the laws.

* ``pareto.csv``, ``pareto.json``, ``pareto.png`` -- the run's archive, one law per row
  (objectives, constraint values and violation, the problem's reported values, the readable
  formula; ``pareto.json`` also the law and what the method reported with it);
* ``summary.json`` -- the report: counts, rates, feasibility, the problem's own report fields;
* ``laws/<k>/`` -- per Pareto law (:mod:`synthesis.fmi.law_files`): ``law.json`` (with the
  readable form), ``law.h``/``law.c`` and the law FMU (native C where a compiler exists), and
  when asked the closed-loop container FMU and its SSP file.
"""
from __future__ import annotations

import csv
import functools
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from descent_fmus.synthesis.fmi.law_files import (LawExport, choose_law_fmu, prefetch_readable,
                                                  readable_text)
from descent_fmus.synthesis.run import readable_ahead
from descent_fmus.synthesis.run.folder import write_json
from descent_fmus.synthesis.run.guard import check_export_space
from descent_fmus.synthesis.run.signals import check_stop, watch_parent

__all__ = ["write_results", "export_law", "plot_front", "feasibility"]


def export_law(problem, law, fmu_dir: Path, dest: Path, description: str = "",
               law_fmu: str = "auto", closed_loop: bool = True, identifier: str | None = None,
               extra: dict | None = None, compiled: bool = False) -> dict:
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
                           extra=dict({"problem": problem.name}, **(extra or {})),
                           compiled=compiled)
    out.pop("note")
    return out


def _rows(problem, front, extras) -> list:
    rows = []
    for k, ((cand, f, cv), ex) in enumerate(zip(front, extras)):
        row = {"k": k}
        row.update({n: float(v) for n, v in zip(problem.objective_names, f)})
        if problem.constraints:
            row["violation"] = float(cv)
            row["feasible"] = cv == 0.0
        row.update({n: v for n, v in ex.items() if isinstance(v, (int, float, bool))})
        row["formula"] = cand.law.formula(6)
        row["readable"] = readable_text(cand.law)
        rows.append(row)
    return rows


def feasibility(problem, evaluator) -> dict:
    """How many evaluated laws met the constraints, and why the best infeasible one did not
    (its constraint values against their bounds)."""
    if not problem.constraints:
        return {}
    outcomes = list(evaluator.cache.values())
    bad = [o for o in outcomes if o.cv > 0]
    out = {"evaluated": len(outcomes), "infeasible": len(bad)}
    if bad:
        best = min(bad, key=lambda o: (o.cv,) + tuple(o.f))
        out["best_infeasible"] = {
            "violation": best.cv,
            "constraints": {c.name: {"value": best.extras.get(c.name), "bound": c.bound,
                                     "sense": c.sense, "over_states": c.over_states}
                            for c in problem.constraints}}
    return out


def structure(problem, archive) -> dict:
    """What the structure search bought: whether the run's best law by the target (the
    problem's CMA-ES target, else its first objective) keeps the basic law's form -- the same
    matrix, only other parameters -- or changed it, and how many Pareto laws did."""
    from descent_fmus.synthesis.methods.registry import cma_target
    if not len(archive):
        return {}
    basic = problem.basic()
    items = archive.items

    def changed(law) -> int:
        if law.psi.shape != basic.psi.shape:
            return int(max(law.psi.size, basic.psi.size))
        return int(np.count_nonzero(law.psi != basic.psi))

    k = int(cma_target(problem).order(archive.F, archive.cv)[0])
    best = items[k][0].law
    n = changed(best)
    out = {"best_law_matrix_changes": n, "best_law_keeps_basic_form": n == 0,
           "pareto_laws_with_new_form": sum(1 for c, _, _ in items if changed(c.law)),
           "best_law": readable_text(best)}
    if "variations" in items[k][0].info:
        out.update(range_edge(problem, best.q))
    return out


def range_edge(problem, q) -> dict:
    """The parameters of a network-operator law that sit at an edge of the Gray code's range
    (``problem.q_bits``): the search could not go further there, so the range is too narrow
    -- ``{"best_law_q_at_range_edge": [1-based indices], "q_range": [lo, hi]}`` or {}."""
    _, _, lo, hi = problem.q_bits
    tol = EDGE_SHARE * (hi - lo)
    edge = [i + 1 for i, v in enumerate(q) if v <= lo + tol or v >= hi - tol]
    return {"best_law_q_at_range_edge": edge, "q_range": [lo, hi]} if edge else {}


#: [choice] a parameter within this share of the range's width from an edge is "at the edge"
EDGE_SHARE = 1e-3


def write_results(problem, archive, evaluator, out: Path, fmu_dir, export,
                  reference: bool, announce=None, timings: dict | None = None) -> dict:
    """Write the Pareto set (the archive's items ``(Candidate, f, cv)``), its figure and, as
    asked by ``export`` (True, False or a :class:`~synthesis.fmi.law_files.LawExport`), the law
    files; the summary fields.  ``announce(text)`` is told each phase; ``timings`` receives
    the seconds of the report, its reference and the export."""
    import time
    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    announce = announce or (lambda text: None)
    announce("writing the report")
    front = archive.sorted()
    laws = [cand.law for cand, _, _ in front]
    readable_ahead.stop()       # what it computed during the search is in the cache folder
    # the figure's imports while the readable forms are computed in other processes
    prefetch_readable(laws, meanwhile=_import_pyplot,
                      initializer=functools.partial(watch_parent, os.getpid()))
    rows = _rows(problem, front, evaluator.evaluate(laws).extras)
    fields = list(dict.fromkeys(key for r in rows for key in r))
    with open(out / "pareto.csv", "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=fields)
        wr.writeheader()
        wr.writerows(rows)

    def pareto_json():
        write_json(out / "pareto.json", [dict(r, law=cand.law.to_dict(), **dict(cand.info))
                                         for r, (cand, _, _) in zip(rows, front)])

    pareto_json()
    basic = evaluator.evaluate([problem.basic()])
    names = problem.objective_names
    summary = {"problem": problem.name, "pareto_size": len(rows),
               "basic_law": dict(zip(names, map(float, basic.F[0])))}
    if problem.constraints:
        summary["basic_law"]["violation"] = float(basic.cv[0])
        summary["feasibility"] = feasibility(problem, evaluator)
    summary["structure"] = structure(problem, archive)
    summary["equivalent_laws_not_flown"] = evaluator.equivalent
    if reference:
        announce("computing the problem's reference")
    t_ref = time.perf_counter()
    summary.update(problem.report.summary(rows, out, reference))
    timings["reference"] = time.perf_counter() - t_ref
    what = LawExport.of(export)
    if what is None:
        plot_front(problem, rows, summary, out / "pareto.png")
    else:
        drawn = _draw_aside(problem, rows, summary, out / "pareto.png")
        ok = False
        try:
            announce(f"exporting {len(rows)} laws")
            t_exp = time.perf_counter()
            _export_laws(problem, rows, laws, what, out, fmu_dir, summary)
            timings["export"] = time.perf_counter() - t_exp
            ok = True
        finally:
            drawn(ok)
        pareto_json()
    timings["report"] = time.perf_counter() - t0 - timings["reference"] - \
        timings.get("export", 0.0)
    summary["pareto"] = rows
    return summary


def _export_laws(problem, rows, laws, what, out, fmu_dir, summary) -> None:
    kind, note = choose_law_fmu(what.law_fmu)
    check_export_space(out, problem, fmu_dir, len(rows), what.closed_loops, law_fmu=kind)
    summary.update(law_fmus=kind, **({"law_fmu_note": note} if note else {}))
    stem = problem.wiring.name.removesuffix("ClosedLoop")

    def one(r, law):
        check_stop()              # a stop requested: no new law is started
        return export_law(problem, law, fmu_dir, out / "laws" / str(r["k"]),
                          description=f"{problem.name} Pareto law {r['k']}",
                          law_fmu=kind, closed_loop=what.closed_loops,
                          identifier=f"{stem}Law{r['k']}", compiled=what.compiled,
                          extra={"k": r["k"], "objectives": {
                              n: r[n] for n in problem.objective_names}})

    # in parallel where a law's export waits mostly for the C compiler (a process of its own;
    # the interpreter law FMU -- no compile -- and a pythonfmu law FMU are Python work, which
    # threads would only interleave); a stop (a signal, an error) cancels the laws not yet
    # started and waits only for those under way, so that the run ends promptly
    threads = min(4, os.cpu_count() or 1) if kind == "native" and what.compiled else 1
    pool = ThreadPoolExecutor(max_workers=threads)
    try:
        futures = [pool.submit(one, r, law) for r, law in zip(rows, laws)]
        for r, f in zip(rows, futures):
            r.update(f.result())
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _draw_aside(problem, rows, summary, path: Path):
    """[choice] ``pareto.png`` drawn in a forked process while this one exports the laws
    (matplotlib's drawing and PNG encoding, ~0.35 s, and the export, ~0.3 s, are both Python
    work, which a thread would only interleave; after the search the second core is free).
    Returns ``finish(ok)``: waits for the drawing, and draws here if the process could not be
    started or failed (so a failure is raised here, as before); ``ok=False`` (the export
    failed or was stopped) ends the process instead."""
    import multiprocessing
    try:
        process = multiprocessing.get_context("fork").Process(
            target=_draw_here, args=(problem, rows, summary, path), daemon=True,
            name="descent-fmus-figure")
        process.start()
    except (ValueError, OSError):           # no fork here
        process = None

    def finish(ok: bool) -> None:
        if process is not None and not ok:
            # SIGKILL: a SIGTERM that lands before _draw_here resets its handler runs the
            # run's stop handler in the child, which prints a traceback
            process.kill()
            process.join()
            return
        if process is not None:
            process.join()
        if ok and (process is None or process.exitcode != 0):
            plot_front(problem, rows, summary, path)
    return finish


def _draw_here(problem, rows, summary, path: Path) -> None:
    """The drawing process's body: ended by the plain SIGTERM (not the run's stop handler),
    deaf to Ctrl-C (the run handles it), silent (a failure is drawn and reported again by the
    run's process)."""
    import signal
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
    plot_front(problem, rows, summary, path)


def _import_pyplot() -> None:
    import matplotlib.pyplot  # noqa: F401


def plot_front(problem, rows, summary, path: Path) -> None:
    """pareto.png: the front, the basic law and (if the report gives one) a reference value of
    objective 1 (``summary["reference"] = {"value": ..., "label": ...}``)."""
    import matplotlib.pyplot as plt

    from descent_fmus.synthesis.plotting import save_figure
    names = problem.objective_names
    if len(names) != 2 or not rows:
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
