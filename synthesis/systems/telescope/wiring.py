"""S4 telescope: the closed loops that fly a computed reorientation (rigid plant + rigid program;
flexible plant + reduced-algorithm program) and the programs they carry.

The programs are the direct method's solutions of the reorientation (Voronov 2009, Examples 1-2),
stored in ``programs.json`` beside this module (written by ``descent-fmus telescope
write-programs``; ``tests/systems/telescope/test_telescope_cli.py`` checks that a fresh solve reproduces them).
The file is read only when a closed-loop FMU is built (:func:`rigid_program`,
:func:`flexible_program`), never at import.

Interface: the ProgramController sends the gimbal rates ``u[j]`` and their slopes ``du[j]``; the
plant integrates ``u + du (t - t_k)`` over the communication step (first-order hold), so the
replay is the solver's piecewise-linear program exactly when the step divides the grid spacing.
"""
from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from descent_fmus.models.telescope import INERTIA_NAMES
from descent_fmus.models.telescope_dynamics import T_DEFAULT
from descent_fmus.synthesis.fmi.closed_loop import STATUS_STOP, Wiring

__all__ = ["STEP", "PLANTS", "PROGRAMS_FILE", "wiring", "WIRING", "FLEXIBLE_WIRING",
           "plant_values", "stored_programs", "rigid_program", "flexible_program"]

#: Communication step [s]: divides the 1 s control grid; 20 plant sub-steps of 0.025 s.
STEP = 0.5
#: The plant FMUs by model: the rigid and the flexible telescope.
PLANTS = {"rigid": "Telescope", "flexible": "FlexibleTelescope"}
#: The stored programs ({"rigid": start values, "flexible": start values}).
PROGRAMS_FILE = Path(__file__).with_name("programs.json")

_TO_PLANT = tuple((f"u[{j}]", f"u[{j}]") for j in range(1, 7)) + \
    tuple((f"du[{j}]", f"du[{j}]") for j in range(1, 7))
_EXPOSED = tuple((n, "plant", n) for n in ("lam0", "lam1", "lam2", "lam3", "w1", "w2", "w3",
                                            "K1", "K2", "K3", "sing", "lam_norm")) + \
    tuple((f"beta{j}", "plant", f"beta{j}") for j in range(1, 7)) + \
    tuple((f"u{j}", "controller", f"u[{j}]") for j in range(1, 7)) + \
    (("status", "plant", "status"), ("t_end", "plant", "t_end"))


def wiring(plant: str) -> Wiring:
    """Wiring of a telescope plant (``"Telescope"`` or ``"FlexibleTelescope"``) with the
    ProgramController (no feedback: a program), up to the reorientation time ``T_DEFAULT``."""
    if plant not in PLANTS.values():
        raise ValueError(f"unknown telescope plant {plant!r}; known: {', '.join(PLANTS.values())}")
    exposed = _EXPOSED
    if plant == "FlexibleTelescope":
        exposed += tuple((f"eta{k}", "plant", f"eta{k}") for k in range(1, 5))
    return Wiring(name=f"{plant}ClosedLoop", plant=plant, controller="ProgramController",
                  to_controller=(), to_plant=_TO_PLANT, step=STEP, stop_time=T_DEFAULT,
                  stop=STATUS_STOP, exposed=exposed,
                  description=f"S4 reorientation (Voronov 2009): {plant} flying the direct "
                              "method's gimbal-rate program (first-order hold)")


WIRING = wiring("Telescope")
FLEXIBLE_WIRING = wiring("FlexibleTelescope")


def plant_values(params, panels=None, dt: float | None = None, state=None) -> dict:
    """Start values of a telescope plant FMU for a ``TelescopeParams`` (its inertia, rotor
    momentum, rotor reference, number of gyrodynes and gimbal axes; and ``PanelParams``), the
    RK4 sub-step ``dt`` [s] and the initial ``state`` (lambda, omega [rad/s], beta [rad]) if
    given."""
    values = dict(zip(INERTIA_NAMES, params.inertia))
    values["h"] = params.h
    values["n_gyros"] = params.n_gyros
    vectors = {"rotor_ref": params.rotor_ref, "gimbal_axes": params.gimbal_axes}
    if panels is not None:
        vectors.update(asdict(panels))
    if state is not None:
        state = tuple(float(v) for v in state)
        vectors.update(lam_init=state[:4], w_init=state[4:7],
                       beta_init=state[7:7 + params.n_gyros])
    for name, vector in vectors.items():
        values.update((f"{name}[{k + 1}]", v) for k, v in enumerate(vector))
    if dt is not None:
        values["dt"] = dt
    return values


def stored_programs(path=PROGRAMS_FILE) -> dict:
    """``{"rigid": {...}, "flexible": {...}}``: ProgramController start values of the stored
    programs."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing: write it with 'descent-fmus telescope "
                                "write-programs'")
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def rigid_program() -> dict:
    """ProgramController start values of TelescopeClosedLoop (the stored rigid program)."""
    return stored_programs()["rigid"]


def flexible_program() -> dict:
    """ProgramController start values of FlexibleTelescopeClosedLoop (the stored flexible
    program, reduced algorithm)."""
    return stored_programs()["flexible"]
