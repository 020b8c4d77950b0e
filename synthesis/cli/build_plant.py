"""``descent-fmus build-plant FILE.py``: a plant written once -> its pythonfmu FMU and its native C
twin, checked against each other bit for bit (:mod:`synthesis.fmi.user_plant`)."""
from __future__ import annotations

from pathlib import Path

from descent_fmus.synthesis.cli.common import (CliError, add_common_options, emit, int_at_least,
                                               positive_float)

__all__ = ["add_build_plant_command"]


def add_build_plant_command(sub) -> None:
    p = sub.add_parser(
        "build-plant", help="build a plant written in the model style as a pythonfmu FMU and its "
        "native C twin, checked bit for bit",
        description="Build DIR/<Plant>.fmu (pythonfmu) and DIR/native/<Plant>.fmu (C generated "
        "from the same class), fly both with the same inputs and keep the twin only if every "
        "output at every communication point is bitwise equal. A problem file naming "
        "DIR/<Plant>.fmu then flies the twin.")
    p.add_argument("plant", type=Path, metavar="FILE.py",
                   help="the plant module (Params dataclass, right-hand side, Integrator "
                        "subclass, FMU class deriving SlaveBase)")
    p.add_argument("-d", "--dest", type=Path, default=None, metavar="DIR",
                   help="output folder (default: the plant file's folder)")
    p.add_argument("--class", dest="class_name", default=None, metavar="NAME",
                   help="the FMU class, if the file defines several")
    p.add_argument("--no-check", action="store_true",
                   help="keep the twin without flying it against the pythonfmu FMU")
    p.add_argument("--check-steps", type=int_at_least(1), default=None, metavar="N",
                   help="communication steps of each check flight (default 100)")
    p.add_argument("--check-step", type=positive_float, default=None, metavar="H",
                   help="communication step of the check flights [s] (default: the FMU's "
                        "default experiment, else 0.1)")
    add_common_options(p, fmus=False)
    p.set_defaults(func=run_build_plant)


def run_build_plant(args) -> int:
    from descent_fmus.synthesis.fmi.user_plant import (CHECK_STEPS, PlantFileError,
                                                              build_plant)
    try:
        r = build_plant(args.plant, args.dest, check=not args.no_check,
                        class_name=args.class_name, steps=args.check_steps or CHECK_STEPS,
                        step=args.check_step)
    except PlantFileError as exc:
        raise CliError(str(exc)) from None
    lines = [f"built {r['pythonfmu']} (pythonfmu, {r['seconds']['pythonfmu']:.1f} s)"]
    if r["native"]:
        lines.append(f"built {r['native']} (native C twin, {r['seconds']['native']:.1f} s)")
    c = r["check"]
    if c is not None:
        if c.get("equal"):
            lines.append(f"check: bitwise equal -- {c['outputs']} outputs at {c['points']} "
                         f"communication points of {c['flights']} flights (step {c['step']:g} s)")
        elif c.get("mismatch"):
            m = c["mismatch"]
            lines.append(f"check: DIFFERENT -- {m['output']} at t = {m['time']:g} s of the "
                         f"{m['flight']} flight: pythonfmu {m['pythonfmu']!r}, native "
                         f"{m['native']!r}")
        else:
            lines.append(f"check: {c.get('error')}")
    elif r["native"]:
        lines.append("check: skipped (--no-check)")
    if r["note"]:
        lines.append(r["note"])
    bad = {p: v for p, v in r.get("validate", {}).items() if v}
    for path, problems in bad.items():
        lines.append(f"fmpy validate {path}: " + "; ".join(problems))
    if not bad:
        lines.append(f"fmpy validate: no problems ({len(r.get('validate', {}))} FMUs)")
    emit(args, r, "\n".join(lines))
    failed = (c is not None and not c.get("equal")) or bool(bad) or "error" in r
    return 1 if failed else 0
