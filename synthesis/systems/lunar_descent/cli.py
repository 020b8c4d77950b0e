"""``descent-fmus lunar-descent report``: S5 laws on the initial-state set and on a seeded
dispersion (thrust +-3 %, specific impulse +-1 %), through the FMUs; optional front comparison
of two synthesis runs."""
from __future__ import annotations

import json
from pathlib import Path

from descent_fmus.synthesis.cli.common import CliError, add_common_options, emit, fmu_folder

__all__ = ["add_commands", "run_report", "HV_REF"]

#: Reference point of the hypervolume comparison [m, m/s]: every state in the box with
#: |h - hf| <= 600 m and |V - Vf| <= 12 m/s on average (5 initial states).
HV_REF = (3000.0, 60.0)


def add_commands(sub) -> None:
    p = sub.add_parser("report", help="a synthesised law vs a baseline on the initial-state set "
                       "and on a seeded dispersion (h, V misses, fuel), through the FMUs")
    p.add_argument("--law", type=Path, required=True, metavar="FILE.json",
                   help="law JSON (laws/<k>/law.json of a synthesis run) or the run's "
                        "pareto.json (row --row)")
    p.add_argument("--row", type=int, default=0, metavar="K",
                   help="row k of a pareto.json given as --law or --baseline (default 0, the "
                        "lowest J1)")
    p.add_argument("--baseline", type=Path, metavar="FILE.json",
                   help="baseline law JSON or pareto.json (default: the problem's basic law, a "
                        "linear feedback law)")
    p.add_argument("--front", type=Path, metavar="PARETO.json",
                   help="pareto.json of the synthesis run")
    p.add_argument("--baseline-front", type=Path, metavar="PARETO.json",
                   help="pareto.json of the baseline run (e.g. synthesize lunar-descent "
                        "--lchr 0): hypervolume comparison")
    p.add_argument("--samples", type=int, default=100, metavar="N",
                   help="dispersion samples (default 100; 0: none)")
    p.add_argument("--seed", type=int, default=7, metavar="S",
                   help="seed of the dispersion samples (default 7)")
    add_common_options(p, plot="write a PNG of h(V) on the initial set and of the final "
                               "|h - hf| of the dispersion")
    p.set_defaults(func=run_report)


def _load_law(path, row: int = 0):
    from descent_fmus.synthesis.methods.law import LawFileError, NetworkOperator
    try:
        data = json.loads(Path(path).read_text())
        if isinstance(data, list):            # a pareto.json: one law per row
            if not 0 <= row < len(data):
                raise CliError(f"{path} has {len(data)} rows; --row must be in 0..{len(data) - 1}")
            data = data[row]["law"]
        return NetworkOperator.from_dict(data)
    except (OSError, ValueError, LawFileError, KeyError, TypeError) as exc:
        raise CliError(f"cannot read law {path}: {exc}") from None


def _load_front(path):
    try:
        rows = json.loads(Path(path).read_text())
        return [(float(r["J1"]), float(r["J2"])) for r in rows]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CliError(f"cannot read front {path} (a pareto.json of a lunar-descent run): "
                       f"{exc}") from None


def run_report(args) -> int:
    from descent_fmus.synthesis.systems.lunar_descent.problems import synthesis_basic_law
    from descent_fmus.synthesis.systems.lunar_descent.study import (front_comparison,
                                                                     plot_study, study)

    if args.samples < 0:
        raise CliError(f"--samples must be >= 0, got {args.samples}")
    laws = {"synthesised": _load_law(args.law, args.row),
            "baseline": _load_law(args.baseline, args.row) if args.baseline
            else synthesis_basic_law()}
    for name, law in laws.items():
        if len(law.outputs) != 2 or law.nx != 4:
            raise CliError(f"the {name} law has {law.nx} inputs and {len(law.outputs)} outputs; "
                           f"a lunar-descent law reads 4 inputs and drives 2 outputs (u1, u2)")
    res = study(laws, fmu_folder(args), args.samples, args.seed, record=bool(args.plot))
    if args.front and args.baseline_front:
        res["front"] = front_comparison(_load_front(args.front), _load_front(args.baseline_front),
                                        HV_REF)
    if args.plot:
        plot_study(res, args.plot)
        res["plot"] = str(args.plot)
    lines = [f"{'law':12s} {'J1 [m]':>9s} {'J2 [m/s]':>9s} {'in box':>7s} {'|dh| max':>9s} "
             f"{'|dV| max':>9s} {'h_min':>7s} {'fuel max':>9s}   set"]
    for name, r in res["laws"].items():
        for what in ("initial_set", "dispersion"):
            s = r[what]
            if s is None:
                continue
            j1, j2 = (f"{r['J1']:9.1f}", f"{r['J2']:9.2f}") if what == "initial_set" \
                else (f"{'':9s}", f"{'':9s}")
            lines.append(f"{name:12s} {j1} {j2} {s['in_box']:3d}/{s['n']:<3d} "
                         f"{s['dh_max']:8.1f}m {s['dV_max']:7.2f}m/s {s['h_min']:6.0f}m "
                         f"{s['fuel_max']:7.1f}kg   {what.replace('_', ' ')}"
                         + (f" ({args.samples} samples, seed {args.seed})"
                            if what == "dispersion" else ""))
    if "front" in res:
        f = res["front"]
        lines.append(f"front hypervolume (ref J1={f['ref'][0]:.0f}, J2={f['ref'][1]:.0f}): "
                     f"synthesised {f['hv_a']:.0f} vs baseline {f['hv_b']:.0f} "
                     f"(x{f['hv_ratio']:.3f}); {f['b_dominated_by_a']}/{f['b_size']} baseline "
                     f"front points dominated")
    for r in res["laws"].values():
        for row in r["rows"]:
            row.pop("trace", None)
        if args.json:
            r.pop("dispersion_points", None)
    emit(args, res, "\n".join(lines))
    return 0
