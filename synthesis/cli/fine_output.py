"""``descent-fmus fine-output``: a closed-loop FMU that ``fmpy simulate`` runs with fine output.

fmpy's container FMU steps the plant and the controller with one fixed step (the closed loop's
communication step, e.g. 1 s for the reentry) and accepts only multiples of it as
``--output-interval``.  This command copies a closed-loop FMU with a finer internal step; the
controller keeps sampling at its own period (the container parameter ``sample_period``), so the
copy shows the same control between finer output points::

    descent-fmus fine-output fmus/ReentryClosedLoop.fmu --step 0.1 --out ReentryFine.fmu
    fmpy simulate ReentryFine.fmu --output-interval 0.1 --show-plot
"""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.cli.common import (CliError, add_common_options, emit,
                                               positive_float)

__all__ = ["add_fine_output_command"]


def add_fine_output_command(sub) -> None:
    p = sub.add_parser("fine-output", help="copy a closed-loop FMU with a finer internal step "
                       "(fmpy simulate --output-interval down to it; the controller keeps its "
                       "sample period)")
    p.add_argument("fmu", type=Path, help="closed-loop FMU (fmus/<Name>ClosedLoop.fmu, "
                   "laws/<k>/<Name>ClosedLoop.fmu of a synthesis run)")
    p.add_argument("--step", type=positive_float, required=True, metavar="S",
                   help="internal step of the copy [s]; output intervals are multiples of it")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.fmu",
                   help="the copy (an existing file is not overwritten)")
    add_common_options(p, fmus=False)
    p.set_defaults(func=run_fine_output)


def run_fine_output(args) -> int:
    from fmpy import read_model_description

    from descent_fmus.synthesis.fmi.containers import refine_container
    if args.out.exists():
        raise CliError(f"{args.out} exists; choose another --out (nothing was overwritten)")
    try:
        out = refine_container(args.fmu, args.out, args.step)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    md = read_model_description(str(out))
    period = next((v.start for v in md.modelVariables if v.name == "sample_period"), None)
    info = {"fmu": str(args.fmu), "out": str(out), "step": args.step,
            "controller_sample_period": None if period is None else float(period)}
    text = (f"wrote {out}: internal step {args.step:g} s"
            + (f", controller sampling every {float(period):g} s" if period is not None else
               " (open-loop program: no sampling)")
            + f"\n  fmpy simulate {out} --output-interval {args.step:g}")
    emit(args, info, text)
    return 0
