"""``descent-fmus mars fly``: the S2 Mars descent with and without the law, through the FMUs."""
from __future__ import annotations

from descent_fmus.synthesis.cli.common import (CliError, add_common_options,
                                               add_parameter_options, emit, fmu_folder,
                                               parameter_overrides)

__all__ = ["add_commands"]

#: Plant parameters the command sets (MarsParams fields).
PLANT_OPTIONS = ("alpha0", "omega_x", "theta1", "eps", "V0", "h_end")
#: Law parameters the command sets (MarsBellmanParams fields).
LAW_OPTIONS = ("b", "c", "u_max")


def add_commands(sub) -> None:
    from descent_fmus.models.controllers.mars_bellman import MarsBellmanParams
    from descent_fmus.models.mars import MarsParams
    from descent_fmus.synthesis.systems.mars.flight import FORMULAS

    p = sub.add_parser("fly", help="alpha(t) of the S2 Mars capsule with and without the "
                       "Bellman law, through the FMUs")
    p.add_argument("--no-control", action="store_true",
                   help="fly only the uncontrolled descent (u = 0)")
    p.add_argument("--formula", choices=[*FORMULAS, "both"], default="consistent",
                   help="gain A of the law: the consistent root of eq. (14) (default), the "
                        "paper's printed root (15) with its guards, or both")
    add_parameter_options(p.add_argument_group("plant (MarsCapsule)"), MarsParams,
                          PLANT_OPTIONS)
    add_parameter_options(p.add_argument_group("law (MarsBellmanController)"),
                          MarsBellmanParams, LAW_OPTIONS)
    add_common_options(p, plot="write a PNG of alpha(t) and u(t) of all runs")
    p.set_defaults(func=run_fly)


def run_fly(args) -> int:
    from descent_fmus.models.controllers.mars_bellman import MarsBellmanParams
    from descent_fmus.models.mars import MarsParams
    from descent_fmus.models.params import ParameterError
    from descent_fmus.synthesis.systems.mars.flight import fly_set, plot_alpha

    plant = parameter_overrides(args, PLANT_OPTIONS)
    ctrl = parameter_overrides(args, LAW_OPTIONS)
    try:   # the FMUs would reject them too; say so before loading them
        MarsParams(**plant).validate()
        MarsBellmanParams(**ctrl).validate()
    except ParameterError as exc:
        raise CliError(str(exc)) from None
    formulas = ("consistent", "paper") if args.formula == "both" else (args.formula,)
    runs = fly_set(fmu_folder(args), control=not args.no_control, formulas=formulas,
                   plant_values=plant, controller_values=ctrl, record=bool(args.plot))
    summary = {"runs": [r.summary() for r in runs]}
    lines = [f"S2 Mars descent to h_end (t_end = {runs[0].result.final['t_end']:.1f} s), "
             f"through the FMUs:"]
    for r in runs:
        lines.append(f"  {r.label:<22} alpha_end = {r.alpha_end:.3e} rad "
                     f"({r.summary()['alpha_end_deg']:.4f} deg)")
    if len(runs) > 1:
        base, ctl = runs[0].alpha_end, runs[1].alpha_end
        ratio = base / ctl if ctl > 0 else None    # None: the law brought alpha to 0
        summary["ratio_uncontrolled_to_controlled"] = ratio
        lines.append(f"  ratio no control / law ({runs[1].label}) = "
                     + (f"{ratio:.3g}" if ratio is not None else "inf"))
    if args.plot:
        plot_alpha(runs, args.plot)
        summary["plot"] = str(args.plot)
        lines.append(f"  plot: {args.plot}")
    emit(args, summary, "\n".join(lines))
    return 0
