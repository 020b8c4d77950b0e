"""S4 telescope: plant FMUs, the program controller and the closed loops that fly the computed
reorientation (rigid plant + rigid program; flexible plant + reduced-algorithm program).

The programs are the direct method's solutions of SPEC S4, stored in
``synthesis/scenarios/telescope_programs.json`` (written by ``python -m synthesis.systems.telescope.reorientation
--write-programs``; tests/test_telescope.py checks that a fresh solve reproduces them).

Interface: the ProgramController sends the gimbal rates ``u[j]`` and their slopes ``du[j]``; the
plant integrates ``u + du (t - t_k)`` over the communication step (first-order hold), so the
replay is the solver's piecewise-linear program exactly when the step divides the grid spacing.
"""
from __future__ import annotations

import json
from pathlib import Path

from descent_fmus.synthesis.cosim import Wiring
from descent_fmus.synthesis.scenarios import ClosedLoopSpec, register

#: Communication step [s]: divides the 1 s control grid; 10 plant sub-steps of 0.05 s.
STEP = 0.5
PROGRAMS_FILE = Path(__file__).with_name("telescope_programs.json")

_TO_PLANT = tuple((f"u[{j}]", f"u[{j}]") for j in range(1, 7)) + \
    tuple((f"du[{j}]", f"du[{j}]") for j in range(1, 7))
_EXPOSED = tuple((n, "plant", n) for n in ("lam0", "lam1", "lam2", "lam3", "w1", "w2", "w3",
                                            "K1", "K2", "K3", "sing", "lam_norm")) + \
    tuple((f"beta{j}", "plant", f"beta{j}") for j in range(1, 7)) + \
    tuple((f"u{j}", "controller", f"u[{j}]") for j in range(1, 7))


def wiring(plant: str) -> Wiring:
    """Wiring of a telescope plant with the ProgramController (no feedback: a program)."""
    exposed = _EXPOSED
    if plant == "FlexibleTelescope":
        exposed += tuple((f"eta{k}", "plant", f"eta{k}") for k in range(1, 5))
    return Wiring(name=f"{plant}ClosedLoop", plant=plant, controller="ProgramController",
                  to_controller=(), to_plant=_TO_PLANT, step=STEP, stop_time=40.0,
                  exposed=exposed,
                  description=f"S4 reorientation (SPEC S4, seed 003): {plant} flying the direct "
                              "method's gimbal-rate program (first-order hold)")


def stored_programs() -> dict:
    """{"rigid": {...}, "flexible": {...}} start values of the ProgramController, or {}."""
    if not PROGRAMS_FILE.is_file():
        return {}
    with open(PROGRAMS_FILE, encoding="utf-8") as fh:
        return json.load(fh)


_progs = stored_programs()
register(
    slaves=["models/telescope.py", "models/flexible_telescope.py",
            "models/controllers/program_table.py"],
    closed_loops=[ClosedLoopSpec(wiring("Telescope"),
                                 controller_defaults=_progs.get("rigid", {})),
                  ClosedLoopSpec(wiring("FlexibleTelescope"),
                                 controller_defaults=_progs.get("flexible", {}))],
)
