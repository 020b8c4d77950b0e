"""Every FMU survives errors: pythonfmu 0.7 over-releases its references when a callback raises
(models/pythonfmu_compat.py); SlaveBase guards every callback of every FMU class, and the
entry module of every FMU balances the reference pythonfmu drops at each instantiation.

Run in a subprocess: without the guard the script dies with SIGSEGV in the garbage collector
after a rejected parameter followed by reset/free (reproduced with Reentry, MarsCapsule and
LunarLander FMUs).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import gc
from descent_fmus.synthesis.fmi.closed_loop import ClosedLoop
from descent_fmus.synthesis.fmi.slave import FMUError
from descent_fmus.synthesis.systems.reentry import wiring as reentry
from descent_fmus.synthesis.systems.mars import wiring as mars
from descent_fmus.synthesis.systems.lunar_landing.problems import FEEDBACK_WIRING, PROGRAM_WIRING
d = {d!r} + "/"
cases = [
    (reentry.WIRING, "Reentry", "NetworkOperatorController",
     [({{"V0": -1.0}}, {{}}), ({{}}, {{"psi[1,5]": 77}})]),
    (mars.WIRING, "MarsCapsule", "MarsBellmanController",
     [({{}}, {{"c": 0.0}}), ({{"omega_x": 0.0}}, {{}}), ({{"Ix": -1.0}}, {{}})]),
    (FEEDBACK_WIRING, "LunarLander", "LandingSwitch", [({{"umax": -1.0}}, {{}}),
                                                      ({{}}, {{"beta": -1.0}})]),
    (PROGRAM_WIRING, "LunarLander", "LandingProgram", [({{}}, {{"t_off": -5.0}})]),
]
for i in range(3):
    for wiring, plant, ctrl, bad in cases:
        with ClosedLoop(wiring, d + plant + ".fmu", d + ctrl + ".fmu") as loop:
            for pv, cv in bad:
                try:
                    loop.run(pv, cv)
                except FMUError:
                    pass
                else:
                    raise SystemExit(f"{{plant}}/{{ctrl}} accepted {{pv}} {{cv}}")
            loop.run()
        gc.collect()
print("survived")
"""


def test_errors_then_reset_and_free_do_not_crash(fmu_dir):
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(d=str(fmu_dir))],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "survived" in out.stdout
