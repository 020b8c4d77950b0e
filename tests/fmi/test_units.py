"""Units in every FMU: the ``unit`` attributes and ``<UnitDefinitions>`` the build writes.

Oracles: the one place a unit is defined (``models.params.param`` metadata, the "[unit]" ending
every description), the SI definitions of the units (BIPM SI brochure: N = kg m s-2,
Pa = kg m-1 s-2, Hz = s-1; the standard kilogram-force 9.80665 N), and fmpy's own reader,
validator and SSP schema check.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from xml.etree import ElementTree as ET

import pytest
from fmpy import read_model_description
from fmpy.ssp.ssd import read_ssd

from descent_fmus.models.params import unit_of
from descent_fmus.models.reentry import ReentryParams
from descent_fmus.synthesis.fmi.description.units import UnitError, base_unit, normalise, unit_of_description


@pytest.mark.parametrize("unit, exps, factor", [
    ("m/s2", {"m": 1, "s": -2}, 1.0),
    ("kg.m2", {"kg": 1, "m": 2}, 1.0),
    ("N.m.s", {"kg": 1, "m": 2, "s": -1}, 1.0),      # angular momentum
    ("Pa/s", {"kg": 1, "m": -1, "s": -3}, 1.0),
    ("rad/s", {"s": -1, "rad": 1}, 1.0),
    ("Hz", {"s": -1}, 1.0),
    ("kgf", {"kg": 1, "m": 1, "s": -2}, 9.80665),
    ("1/rad", {"rad": -1}, 1.0),
    ("1", {}, 1.0),
])
def test_si_exponents(unit, exps, factor):
    assert base_unit(unit) == (exps, pytest.approx(factor, rel=1e-15))


def test_spellings():
    assert normalise("N m s") == "N.m.s"
    assert base_unit("sqrt(kg).m") is None          # half-integer exponent: FMI 2.0 cannot
    assert unit_of_description("altitude r - Rz [m]") == "m"
    assert unit_of_description("a plain description") is None
    with pytest.raises(UnitError, match="unknown unit symbol 'furlong'"):
        base_unit("furlong/s")
    # a bracket that is not a unit is text: no unit (a user's plant described its input as
    # "force, clipped to [-2, 2]" and its build failed on it); strict names it
    assert unit_of_description("force, clipped to [-2, 2]") is None
    assert unit_of_description("speed [furlong/s]") is None
    with pytest.raises(UnitError, match=r"clipped to \[-2, 2\].*'-2,'"):
        unit_of_description("force, clipped to [-2, 2]", strict=True)
    assert unit_of_description("speed [N m/s]", strict=True) == "N.m/s"


def _variables(path):
    """(name, type element, description) of every ScalarVariable and the unit definitions."""
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    svs = [(sv.get("name"), sv[0], sv.get("description")) for sv in root.iter("ScalarVariable")]
    defs = {u.get("name"): u for u in root.iter("Unit")}
    return svs, defs


def test_every_variable_with_a_unit_carries_it(fmu_dir):
    fmus = sorted(fmu_dir.glob("*.fmu"))
    assert len(fmus) >= 20
    checked = 0
    for path in fmus:
        svs, defs = _variables(path)
        for name, kind, description in svs:
            unit = unit_of_description(description, strict=True)    # no misspelt unit
            if unit is None or kind.tag != "Real":     # FMI 2.0: only Real has a unit
                continue
            assert kind.get("unit") == unit, f"{path.name}: {name}"
            assert unit in defs, f"{path.name}: unit {unit} of {name} is not defined"
            base = base_unit(unit)
            bu = defs[unit].find("BaseUnit")
            if base is None:
                assert bu is None
            else:
                got = {k: int(v) for k, v in bu.attrib.items() if k != "factor"}
                assert got == base[0], f"{path.name}: {unit}"
            checked += 1
    assert checked > 500


def test_units_come_from_the_parameter_definitions(fmu_dir):
    md = read_model_description(str(fmu_dir / "Reentry.fmu"))
    units = {v.name: v.unit for v in md.modelVariables}
    for name in ("m", "V0", "h0", "rho0"):
        assert units[name] == unit_of(ReentryParams, name)
    assert (units["h"], units["L"], units["y2"], units["t_end"]) == ("m", "m", "rad", "s")


def test_fmpy_info_shows_the_plant_units(fmu_dir):
    r = subprocess.run([sys.executable, "-c", "import sys; from fmpy.cli import main; "
                        "sys.argv[0] = 'fmpy'; main()", "info", str(fmu_dir / "Reentry.fmu")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split() for line in r.stdout.splitlines()
            if line.startswith("  ") and len(line.split()) > 3}
    assert rows["h"][3] == "m" and rows["x2"][3] == "m/s"


def test_container_and_ssp_carry_the_units(fmu_dir):
    md = read_model_description(str(fmu_dir / "MarsClosedLoop.fmu"))
    units = {v.name: v.unit for v in md.modelVariables}
    assert units["time"] == "s" and units["alpha"] == "rad" and units["V0"] == "m/s"
    read_ssd(str(fmu_dir / "MarsClosedLoop.ssp"), validate=True)      # schema-checked
    with zipfile.ZipFile(fmu_dir / "MarsClosedLoop.ssp") as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    ssd, ssc = ("{http://ssp-standard.org/SSP1/SystemStructure%s}" % k
                for k in ("Description", "Common"))
    conn = {(c.get("name")): c[0].get("unit") for comp in root.iter(ssd + "Component")
            if comp.get("name") == "plant" for c in comp.iter(ssd + "Connector")}
    assert conn["alpha"] == "rad" and conn["omega_dot"] == "rad/s2"
    defs = {u.get("name"): u.find(ssc + "BaseUnit").attrib for u in root.iter(ssc + "Unit")}
    assert defs["rad/s2"] == {"s": "-2", "rad": "1"}
