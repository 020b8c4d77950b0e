"""Helpers of the tests that drive an FMU by its FMI calls (fmpy's ``FMU2Slave``): the bits of a
double, and an instance started with given start values.  Used by the native FMU tests of
``tests/fmi/native/`` and of the systems that fly native controllers (``tests/systems/``)."""
from __future__ import annotations

import struct


def bits(v: float) -> bytes:
    """The IEEE 754 bytes of ``v`` (two doubles compare bitwise as their bits)."""
    return struct.pack("<d", v)


def start(fmu, values: dict) -> dict:
    """Reset, set start values (those the FMU has), initialise; the value references."""
    vr = {v.name: v.valueReference for v in fmu.model.modelVariables}
    fmu.reset()
    ints = {k: v for k, v in values.items() if isinstance(v, int) and k in vr}
    reals = {k: float(v) for k, v in values.items() if not isinstance(v, int) and k in vr}
    if ints:
        fmu.setInteger([vr[k] for k in ints], list(ints.values()))
    if reals:
        fmu.setReal([vr[k] for k in reals], list(reals.values()))
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return vr
