"""The benchmark suite's report: the tables of ``suite_table.py`` printed, and the learning curves.

:func:`print_table` prints one problem's rows (median, ratio to the reference, the values per
seed), the verdict against the best baseline, the goal and the network operator's best law;
:func:`plot` draws the best value of the target objective against flights, every method and
seed, one panel per problem (:func:`figure_path`: one figure per half of ``split.toml``).
"""
from __future__ import annotations

import math
from pathlib import Path

from suite_table import CLEARLY, NETWORK_OPERATOR, NOP_LCHR0, _median, value_at

__all__ = ["print_table", "plot", "figure_path"]


def _fmt(v, digits=5) -> str:
    if v is None or v != v:
        return "-"
    if v == math.inf:
        return "inf"
    a = abs(v)
    if a != 0 and (a < 1e-3 or a >= 1e5):
        return f"{v:.3e}"
    return f"{v:.{digits}g}"


def print_table(table: dict, seeds, at=()) -> None:
    """Every problem's rows; ``at`` (flight counts): each method's values read off its runs'
    learning curves at those budgets (:func:`suite_table.value_at`) as well."""
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
        for n in at:                     # a run shorter than n flights has no value there
            for r in t["rows"]:
                vals = [value_at(r["curves"].get(s, []), n) if (f or 0) >= n else math.nan
                        for s, f in zip(seeds, r["flights"])]
                print(f"  at {n} flights: {r['method']:18s} median {_fmt(_median(vals), 7)}"
                      f"  per seed {', '.join(_fmt(v) for v in vals)}")
        v = t["verdict"]
        if "best_baseline" in v:
            print(f"  network operator / best baseline ({v['best_baseline']}): "
                  f"{_fmt(v.get('no_over_best_baseline'), 4)}; at least as good: "
                  f"{'yes' if v.get('at_least_as_good') else 'no'}; clearly better (<= "
                  f"{CLEARLY} x): {'yes' if v.get('clearly_better') else 'no'}")
        if "goal_met" in v:
            print(f"  goal met: {'yes' if v['goal_met'] else 'no'}")
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


# -- the figure --------------------------------------------------------------------------------
def plot(table: dict, path: Path, title: str = "") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(table)
    cols = min(3, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(max(5.2 * cols, 7.0), 4.0 * rows),
                             squeeze=False)
    for ax, name in zip(axes.ravel(), names):
        t = table[name]
        ref = t["reference"]
        excess = t.get("plot") == "excess" and ref
        low = []
        for k, r in enumerate(t["rows"]):
            for j, (seed, curve) in enumerate(sorted(r["curves"].items(),
                                                     key=lambda kv: int(kv[0]))):
                if not curve:
                    continue
                n, v = map(list, zip(*curve))
                n.append(max(n[-1], max(f or 0 for f in r["flights"])))
                v.append(v[-1])
                if excess:
                    v = [max(x / ref - 1.0, 1e-12) for x in v]
                low.append(min(v))
                ax.step(n, v, where="post", color=f"C{k}", alpha=0.85, lw=1.2,
                        label=r["method"] if j == 0 else None)
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
                 "of the target objective against flights, every method and seed",
                 fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def figure_path(base: Path, half: str) -> Path:
    """The learning-curve figure of one half: ``suite.png`` -> ``suite-tuning.png``,
    ``suite-held-out.png``."""
    return base.with_name(f"{base.stem}-{half.replace('_', '-')}{base.suffix}")
