"""``descent-fmus land``: S3 lunar landing -- shooting solve, figures, closed loops via FMUs."""
from __future__ import annotations

import math
from pathlib import Path

from descent_fmus.synthesis.cli import CliError, emit

FMU_DIR = Path(__file__).resolve().parents[2] / "fmus"


def _guess_value(text: str):
    if text.lower() == "auto":
        return None
    try:
        v = float(text)
    except ValueError:
        raise CliError(f"--guess values must be numbers (psi3 may be 'auto'), got {text!r}") \
            from None
    if not math.isfinite(v):
        raise CliError(f"--guess values must be finite, got {text!r}")
    return v


def register(sub) -> None:
    p = sub.add_parser("land", help="S3 lunar soft landing: Pontryagin shooting (seed 002), "
                       "the paper's figures, closed loops through the FMUs")
    p.add_argument("--umax", type=float, default=14.57,
                   help="maximum fuel flow [kg/s] (default 14.57; the paper prints 15.74, a "
                        "misprint: its numbers match 14.57)")
    p.add_argument("--h0", type=float, default=150.0, help="initial altitude [m]")
    p.add_argument("--V0", type=float, default=8.2, help="initial downward speed [m/s]")
    p.add_argument("--method", choices=["interpolate", "event"], default="event",
                   help="switch handling: 'interpolate' = the paper's RK4 with the switch "
                        "interpolated and the control averaged in the step (Fedorenko); 'event' "
                        "= DOP853 with the switch located as an event (default)")
    p.add_argument("--guess", nargs=3, metavar=("PSI1", "PSI3", "T"), default=None,
                   help="starting guess psi1(0) psi3(0) T (default: the paper's guess I, "
                        "-0.15 -0.7 15); PSI3 'auto' = eq. (8) (switch at T/2)")
    p.add_argument("--damped", action="store_true",
                   help="modified (damped) Newton instead of the classical one")
    p.add_argument("--n-steps", type=int, default=1000,
                   help="RK4 steps of the interpolate method (paper: 1000 -> 0.0164 s)")
    p.add_argument("--tol", type=float, default=None,
                   help="max |residual| to stop at (default 1e-5 interpolate, 1e-10 event)")
    p.add_argument("--table1", action="store_true",
                   help="also run the paper's three starting guesses (Table 1), classical and "
                        "modified Newton")
    p.add_argument("--plot", type=Path, default=Path("lunar_landing.png"),
                   help="PNG of the paper's Figs. 1-2 (default lunar_landing.png)")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    p.add_argument("--fly", action="store_true",
                   help="fly the program and the feedback closed loops through the FMUs")
    p.add_argument("--dispersion", type=int, default=0, metavar="N",
                   help="fly N seeded dispersed starts (h0, V0 +-10 %%, gL +-2 %%) + 8 corners "
                        "with both laws through the FMUs")
    p.add_argument("--seed", type=int, default=2017, help="seed of the dispersion")
    p.add_argument("--dispersion-plot", type=Path, default=None,
                   help="PNG of the dispersion (touchdown speeds, phase trajectories)")
    p.add_argument("--fmus", type=Path, default=FMU_DIR, help="folder of the built FMUs")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args) -> int:
    from descent_fmus.models.fmu_support import ParameterError
    from descent_fmus.models.lunar_landing import LanderParams
    from descent_fmus.synthesis.systems.lunar_landing.study import solve_landing
    from descent_fmus.synthesis.methods.shooting import ShootingError

    if args.n_steps < 2:
        raise CliError(f"--n-steps must be >= 2, got {args.n_steps}")
    if args.tol is not None and not (math.isfinite(args.tol) and args.tol > 0.0):
        raise CliError(f"--tol must be > 0, got {args.tol}")
    if args.dispersion < 0:
        raise CliError(f"--dispersion must be >= 0, got {args.dispersion}")
    p = LanderParams(umax=args.umax, h0=args.h0, V0=args.V0)
    guess = (-0.15, -0.7, 15.0) if args.guess is None else tuple(_guess_value(g)
                                                                 for g in args.guess)
    if guess[0] is None or guess[2] is None:
        raise CliError("only PSI3 may be 'auto' in --guess")
    try:
        p.require_stoppable()
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
        from descent_fmus.synthesis.systems.lunar_landing.problems import PAPER_GUESSES, PAPER_ITERATIONS
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
        summary["table1"] = rows
    if not args.no_plot:
        from descent_fmus.synthesis.systems.lunar_landing.study import plot_solution
        try:
            plot_solution(sol, args.plot)
        except OSError as exc:
            raise CliError(f"cannot write {args.plot}: {exc}") from None
        summary["plot"] = str(args.plot)
        lines.append(f"  figures: {args.plot}")
    if args.fly or args.dispersion:
        _closed_loops(args, p, summary, lines)
    emit(args, summary, "\n".join(lines))
    return 0


def _json_float(v):
    """A float for JSON: None instead of NaN/inf (e.g. no touchdown before t+)."""
    return v if math.isfinite(v) else None


def _closed_loops(args, p, summary, lines):
    from descent_fmus.synthesis.cosim import FMUError, FMUNotFoundError
    from descent_fmus.synthesis.systems.lunar_landing.study import LandingLoops, dispersion, dispersion_table, plot_dispersion

    try:
        loops = LandingLoops(args.fmus, nominal=p)
    except FMUNotFoundError as exc:
        raise CliError(str(exc)) from None
    try:
        with loops:
            flights = {}
            for law in ("program", "feedback"):
                td, _ = loops.fly(law)
                flights[law] = dict(touched_down=td.touched_down,
                                    V_touchdown=_json_float(td.V_touchdown),
                                    t_touchdown=_json_float(td.t_touchdown), fuel=td.fuel,
                                    soft=td.soft)
                lines.append(f"  {law} closed loop (FMUs): touchdown at t = "
                             f"{td.t_touchdown:.4f} s, V = {td.V_touchdown:+.4f} m/s, "
                             f"fuel {td.fuel:.2f} kg" if td.touched_down else
                             f"  {law} closed loop (FMUs): no touchdown by t+")
            summary["closed_loop"] = flights
            if args.dispersion:
                rows = dispersion(loops, n=args.dispersion, seed=args.seed)
                text, disp = dispersion_table(rows)
                for s in disp.values():
                    s["worst_speed"] = _json_float(s["worst_speed"])
                    s["median_speed"] = _json_float(s["median_speed"])
                summary["dispersion"] = disp
                lines.append(f"  dispersion (seed {args.seed}):")
                lines.extend("    " + ln for ln in text.splitlines())
                if args.dispersion_plot:
                    plot_dispersion(loops, rows, args.dispersion_plot)
                    summary["dispersion_plot"] = str(args.dispersion_plot)
                    lines.append(f"  dispersion plot: {args.dispersion_plot}")
    except FMUError as exc:
        raise CliError(str(exc)) from None
