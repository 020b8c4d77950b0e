"""``descent-fmus lunar-landing solve | fly``: S3 shooting solve and closed loops via the FMUs."""
from __future__ import annotations

import math

from descent_fmus.models.lunar_landing import LanderParams
from descent_fmus.synthesis.cli.common import (CliError, add_common_options,
                                               add_parameter_options, emit, fmu_folder,
                                               int_at_least, nonnegative_int,
                                               parameter_overrides, positive_float)

__all__ = ["add_commands"]

#: Plant parameters both actions take as options (defaults and help from LanderParams).
PLANT_OPTIONS = ("umax", "h0", "V0")


def add_commands(sub) -> None:
    s = sub.add_parser("solve", help="Pontryagin shooting (Mozzhorina 2017) beside the "
                       "closed-form optimum; the paper's Table 1 and figures")
    add_parameter_options(s, LanderParams, PLANT_OPTIONS)
    s.add_argument("--method", choices=["interpolate", "event"], default="event",
                   help="switch handling: 'interpolate' = the paper's RK4 with the switch "
                        "interpolated and the control averaged in the step (Fedorenko); 'event' "
                        "= DOP853 with the switch located as an event (default)")
    s.add_argument("--guess", nargs=3, metavar=("PSI1", "PSI3", "T"), default=None,
                   help="starting guess psi1(0) psi3(0) T (default: the paper's guess I, "
                        "-0.15 -0.7 15); PSI3 'auto' = the paper's eq. (8) (switch at T/2)")
    s.add_argument("--damped", action="store_true",
                   help="modified (damped) Newton instead of the classical one")
    s.add_argument("--n-steps", type=int_at_least(2), default=1000, metavar="N",
                   help="RK4 steps of the interpolate method (paper: 1000 -> 0.0164 s)")
    s.add_argument("--tol", type=positive_float, default=None, metavar="X",
                   help="max |residual| to stop at (default 1e-5 interpolate, 1e-10 event)")
    s.add_argument("--table1", action="store_true",
                   help="also run the paper's three starting guesses (Table 1), classical and "
                        "modified Newton")
    add_common_options(s, fmus=False, plot="write a PNG of the paper's Figs. 1-2 (V, h, m vs t; "
                       "phase plane)")
    s.set_defaults(func=run_solve)

    f = sub.add_parser("fly", help="fly the optimal program and the feedback law (switching "
                       "curve) through the FMUs; optionally a seeded dispersion")
    add_parameter_options(f, LanderParams, PLANT_OPTIONS)
    f.add_argument("--dispersion", type=nonnegative_int, default=0, metavar="N",
                   help="also fly N seeded dispersed starts (h0, V0 +-10 %%, gL +-2 %%) + the 8 "
                        "corners of the box with both laws")
    f.add_argument("--seed", type=int, default=2017, help="seed of the dispersion (default 2017)")
    add_common_options(f, plot="write a PNG of the dispersion (touchdown speeds, phase "
                       "trajectories); needs --dispersion")
    f.set_defaults(func=run_fly)


def _params(args) -> LanderParams:
    """The plant parameters of the command line, checked (CliError with the reason)."""
    from descent_fmus.models.params import ParameterError
    try:
        return LanderParams(**parameter_overrides(args, PLANT_OPTIONS)).require_stoppable()
    except ParameterError as exc:          # includes InfeasibleLandingError
        raise CliError(f"infeasible data: {exc}") from None


def _guess(values) -> tuple:
    if values is None:
        from descent_fmus.synthesis.systems.lunar_landing.solution import DEFAULT_GUESS
        return DEFAULT_GUESS
    out = []
    for k, text in enumerate(values):
        if text.lower() == "auto" and k == 1:
            out.append(None)
            continue
        try:
            v = float(text)
        except ValueError:
            raise CliError(f"--guess values must be numbers (only PSI3 may be 'auto'), got "
                           f"{text!r}") from None
        if not math.isfinite(v):
            raise CliError(f"--guess values must be finite, got {text!r}")
        out.append(v)
    return tuple(out)


def run_solve(args) -> int:
    from descent_fmus.models.params import ParameterError
    from descent_fmus.synthesis.methods.shooting import ShootingError
    from descent_fmus.synthesis.systems.lunar_landing.solution import solve_landing

    p = _params(args)
    guess = _guess(args.guess)
    try:
        sol = solve_landing(p, guess, method=args.method, damped=args.damped,
                            n_steps=args.n_steps, tol=args.tol)
    except ParameterError as exc:           # includes InfeasibleLandingError
        raise CliError(f"infeasible data: {exc}") from None
    except ShootingError as exc:
        raise CliError(str(exc)) from None
    summary = sol.summary()
    ex = sol.exact
    rel = summary["relative_error"]
    lines = [f"S3 lunar landing, umax = {p.umax} kg/s, h0 = {p.h0} m, V0 = {p.V0} m/s "
             f"({args.method}, {'modified' if args.damped else 'classical'} Newton)",
             f"  {'':14} {'shooting':>16} {'exact (closed form)':>20} {'rel. diff':>10}"]
    for key, label in (("t_switch", "t_switch [s]"), ("T", "T [s]"),
                       ("V_switch", "V_switch [m/s]"), ("h_switch", "h_switch [m]"),
                       ("fuel", "fuel [kg]"), ("psi1", "psi1(0)"), ("psi3_0", "psi3(0)")):
        lines.append(f"  {label:14} {summary[key]:16.10g} {getattr(ex, key):20.10g} "
                     f"{rel[key]:10.2e}")
    r = sol.result
    lines.append(f"  Newton iterations: {r.iterations}, max |residual| = {r.residual_norm:.3e} "
                 f"(from {r.initial_residual_norm:.4g}), integrations: {r.evaluations}")
    if args.table1:
        summary["table1"] = _table1(args, p, lines)
    if args.plot:
        from descent_fmus.synthesis.systems.lunar_landing.solution import plot_solution
        plot_solution(sol, args.plot)
        summary["plot"] = str(args.plot)
        lines.append(f"  figures: {args.plot}")
    emit(args, summary, "\n".join(lines))
    return 0


def _table1(args, p, lines) -> list:
    """The paper's three guesses, classical and modified Newton (rows for the summary)."""
    from descent_fmus.synthesis.methods.shooting import ShootingError
    from descent_fmus.synthesis.systems.lunar_landing.problems import (PAPER_GUESSES,
                                                                       PAPER_ITERATIONS)
    from descent_fmus.synthesis.systems.lunar_landing.solution import solve_landing
    rows = []
    lines.append("  Table 1 (paper: 4, 6, 5 iterations, classical = modified):")
    for g, paper in zip(PAPER_GUESSES, PAPER_ITERATIONS):
        row = {"guess": list(g), "paper": paper}
        for damped in (False, True):
            try:
                s = solve_landing(p, g, method=args.method, damped=damped,
                                  n_steps=args.n_steps, tol=args.tol)
                row["modified" if damped else "classical"] = s.result.iterations
            except ShootingError as exc:
                row["modified" if damped else "classical"] = f"failed: {exc}"
        rows.append(row)
        lines.append(f"    guess {g}: classical {row['classical']}, modified "
                     f"{row['modified']} (paper {paper})")
    return rows


def run_fly(args) -> int:
    from descent_fmus.synthesis.systems.lunar_landing.study import (LAWS, LandingLoops,
                                                                    dispersion, dispersion_table,
                                                                    finite_or_none,
                                                                    plot_dispersion)
    if args.plot and not args.dispersion:
        raise CliError("--plot draws the dispersion figure: give --dispersion N as well")
    p = _params(args)
    summary = {"params": {k: getattr(p, k) for k in PLANT_OPTIONS}, "closed_loop": {}}
    lines = [f"S3 lunar landing through the FMUs, umax = {p.umax} kg/s, h0 = {p.h0} m, "
             f"V0 = {p.V0} m/s"]
    with LandingLoops(fmu_folder(args), nominal=p) as loops:
        for law in LAWS:
            td, _ = loops.fly(law)
            summary["closed_loop"][law] = td.summary()
            lines.append(f"  {law} closed loop: touchdown at t = {td.t_touchdown:.4f} s, "
                         f"V = {td.V_touchdown:+.4f} m/s, fuel {td.fuel:.2f} kg"
                         if td.touched_down else f"  {law} closed loop: no touchdown by t+")
        if args.dispersion:
            rows = dispersion(loops, n=args.dispersion, seed=args.seed)
            text, disp = dispersion_table(rows)
            summary["dispersion"] = dict(samples=args.dispersion, seed=args.seed,
                                         laws=finite_or_none(disp))
            lines.append(f"  dispersion (seed {args.seed}):")
            lines.extend("    " + ln for ln in text.splitlines())
            if args.plot:
                plot_dispersion(loops, rows, args.plot)
                summary["plot"] = str(args.plot)
                lines.append(f"  dispersion plot: {args.plot}")
    emit(args, summary, "\n".join(lines))
    return 0
