"""The benchmark suite's report: the tables of ``suite_table.py`` printed, and the learning curves.

:func:`print_table` prints one problem's rows (median, ratio to the reference, the values per
seed), the verdict against the best baseline, the goal and the network operator's best law;
:func:`print_budgets` every method's values at fixed budgets (5 000 and 20 000 flights) with
the network operator's ratio to GP; :func:`plot` draws the best value of the target objective
against flights, every method's median over the seeds and each seed, one panel per problem
(:func:`figure_path`: one figure per half of ``split.toml``).
"""
from __future__ import annotations

import math
from pathlib import Path

from suite_table import CLEARLY, NETWORK_OPERATOR, NOP_LCHR0, median_curve

__all__ = ["print_table", "print_budgets", "plot", "figure_path"]


def _fmt(v, digits=5) -> str:
    if v is None or v != v:
        return "-"
    if v == math.inf:
        return "inf"
    a = abs(v)
    if a != 0 and (a < 1e-3 or a >= 1e5):
        return f"{v:.3e}"
    return f"{v:.{digits}g}"


def print_table(table: dict, seeds) -> None:
    """Every problem's rows."""
    for name, t in table.items():
        print(f"\n== {name}: reference {_fmt(t['reference'], 7)} ({t['reference_label']}); "
              f"goal: {t['goal']}")
        if t.get("reference_note"):
            print(f"  reference: {t['reference_note']}")
        print(f"  {'method':18s} {'median':>11s} {'ratio':>9s}  per seed "
              f"({', '.join(map(str, seeds))})")
        for r in t["rows"]:
            per = ", ".join(_fmt(v) for v in r["values"])
            print(f"  {r['method']:18s} {_fmt(r['median'], 7):>11s} {_fmt(r['ratio'], 5):>9s}"
                  f"  {per}" + (f"  [{r['details']}]" if r.get("details") else ""))
        v = t["verdict"]
        if "best_baseline" in v:
            print(f"  network operator / best baseline ({v['best_baseline']}): "
                  f"{_fmt(v.get('no_over_best_baseline'), 4)}; at least as good: "
                  f"{'yes' if v.get('at_least_as_good') else 'no'}; clearly better (<= "
                  f"{CLEARLY} x): {'yes' if v.get('clearly_better') else 'no'}")
        if "goal_met" in v:
            k, m = v["seeds_meeting_goal"]
            print(f"  goal met: {'yes' if v['goal_met'] else 'no'} (the median); seeds "
                  f"meeting it: {k} of {m}")
        no = next((r for r in t["rows"] if r["method"] == NETWORK_OPERATOR), None)
        if no is not None:
            form = ("keeps the basic law's form" if no["keeps_basic_form"]
                    else "a new form" if no["keeps_basic_form"] is not None else "?")
            print(f"  network operator's best law (seed {no['median_seed']}, {form}): "
                  f"{no['law']}")
        if "lchr0_median" in v:
            print(f"  the same recipe without structure variations ({NOP_LCHR0}): median "
                  f"{_fmt(v['lchr0_median'], 7)}; network operator / it: "
                  f"{_fmt(v.get('no_over_lchr0'), 4)} (what the form bought, if the form is new)")


# -- every method at fixed budgets --------------------------------------------------------------
def print_budgets(at: dict, seeds) -> None:
    """:func:`suite_table.at_budgets`' table: per problem and method the median and the values
    per seed at each budget ("-": no run gives it), then NO / GP as the issue's goal reads
    it (above a reference: the ratio of the excesses over it, the raw ratio beside it;
    :func:`suite_table.no_over_gp`)."""
    for name, t in at.items():
        if not t["rows"]:
            continue
        print(f"\n== {name} at fixed budgets (median; per seed {', '.join(map(str, seeds))})")
        for r in t["rows"]:
            cells = [f"{n}: {_fmt(r['median'][n], 5)} ("
                     + ", ".join(_fmt(v) if v is not None else "-" for v in r["values"][n])
                     + ")" for n in t["budgets"]]
            print(f"  {r['method']:18s} " + "; ".join(cells))
            meeting = [f"{n}: {k} of {m} (<= {_fmt(t['goals'][n], 4)})"
                       for n, (k, m) in r.get("meeting", {}).items() if m]
            if meeting:
                print(f"  {'':18s} seeds meeting the goal: " + "; ".join(meeting))
        of = t.get("no_over_gp_of", "value")
        if "no_over_gp" in t:
            print(f"  network operator / GP ({of}): "
                  + "; ".join(f"{n}: {_fmt(t['no_over_gp'][n], 3)}" for n in t["budgets"]))
        if "values_no_over_gp" in t:
            print("  raw values, NO / GP (not the goal's comparison: both are at least the "
                  "reference): " + "; ".join(f"{n}: {_fmt(t['values_no_over_gp'][n], 3)}"
                                            for n in t["budgets"]))


# -- the figure --------------------------------------------------------------------------------
def _scaled(curve, ref, excess):
    n, v = map(list, zip(*curve))
    if excess:
        v = [max(x / ref - 1.0, 1e-12) for x in v]
    return n, v


def plot(at: dict, path: Path, title: str = "") -> dict:
    """The learning curves of every method of every problem of ``at`` (the table of
    :func:`suite_table.at_budgets`), one panel per problem: each method's median over the seeds
    (:func:`suite_table.median_curve`, thick) and each seed's curve (thin), the value over the
    reference minus 1 where ``plot = "excess"``.  Returns the median curves drawn
    (``{problem: {method: [[flights, value], ...]}}``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [n for n in at if at[n]["rows"]]
    cols = min(3, max(len(names), 1))
    rows = max(math.ceil(len(names) / cols), 1)
    fig, axes = plt.subplots(rows, cols, figsize=(max(5.2 * cols, 7.0), 4.0 * rows),
                             squeeze=False)
    drawn = {}
    for ax, name in zip(axes.ravel(), names):
        t = at[name]
        ref = t["reference"]
        excess = bool(t.get("plot") == "excess" and ref)
        low, drawn[name] = [], {}
        for k, r in enumerate(t["rows"]):
            for seed, curve in r["curves"].items():
                if curve:
                    n, v = _scaled(curve + [[max(curve[-1][0], r["ends"][seed]), curve[-1][1]]],
                                   ref, excess)
                    low.append(min(v))
                    ax.step(n, v, where="post", color=f"C{k}", alpha=0.35, lw=0.7)
            med = median_curve(r["curves"], r["ends"])
            drawn[name][r["method"]] = med
            if med:
                n, v = _scaled(med, ref, excess)
                ax.step(n, v, where="post", color=f"C{k}", lw=2.0,
                        label=f"{r['method']} (median of {len(r['curves'])})")
        if excess:
            if t.get("goal_ratio"):
                ax.axhline(t["goal_ratio"] - 1.0, color="k", ls=":", lw=1,
                           label=f"goal {t['goal_ratio']:g} x reference")
            ax.set_ylabel("value / reference - 1")
        elif ref is not None and (not low or ref > 1e-3 * min(low)):
            ax.axhline(ref, color="k", ls="--", lw=1, label=f"reference {ref:.4g}")
        elif ref is not None:
            ax.text(0.02, 0.02, f"reference {ref:.2g} (off the scale)", transform=ax.transAxes,
                    fontsize=8)
        ax.set_yscale("log")
        ax.set_xlabel("flights")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    fig.suptitle("benchmark suite" + (f": {title}" if title else "") + "\nthe best value "
                 "of the target objective against flights:\nevery method's median over the "
                 "seeds (thick) and each seed (thin)", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return drawn


def figure_path(base: Path, half: str) -> Path:
    """The learning-curve figure of one half: ``suite.png`` -> ``suite-tuning.png``,
    ``suite-held-out.png``."""
    return base.with_name(f"{base.stem}-{half.replace('_', '-')}{base.suffix}")
