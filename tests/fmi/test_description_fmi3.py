"""The FMI 3.0 model description writer on every kind of variable it takes (the native FMUs
have Reals and Integers only; tests/fmi/native/test_native_fmi3.py checks those).

Oracles: fmpy's validation (the FMI 3.0 schema and rules) and fmpy's reading of the file; the
FMI 3.0 standard's rules for the attributes (an Int32 or Boolean is not continuous, an output
is calculated and has no start, `time` is the one independent variable).
"""
from __future__ import annotations

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from descent_fmus.synthesis.fmi.description.fmi3 import Row, build_description, model_description

ROWS = [Row("x", 0, "input", "continuous", "Real", 1.5, "position [m]"),
        Row("n", 1, "input", "continuous", "Integer", 3, "count"),
        Row("on", 2, "parameter", "fixed", "Boolean", True, "switch"),
        Row("k", 3, "parameter", "tunable", "Real", 0.1, "gain [1/s]"),
        Row("y", 4, "output", "continuous", "Real", None, "speed [m/s]"),
        Row("c", 5, "output", "continuous", "Integer", None, "status")]


def test_every_kind_of_variable(tmp_path):
    (tmp_path / "modelDescription.xml").write_bytes(
        model_description("M", "{token}", "a model", ROWS, {"stopTime": 2.0}, "a tool"))
    assert validate_fmu(str(tmp_path)) == []
    md = read_model_description(str(tmp_path))
    assert md.fmiVersion == "3.0" and md.instantiationToken == "{token}"
    assert md.defaultExperiment.stopTime == "2.0"
    # (an input has no initial attribute: fmpy gives the default, "exact")
    got = {v.name: (v.type, v.causality, v.variability, v.initial, v.start, v.unit,
                    v.valueReference) for v in md.modelVariables}
    assert got == {
        "time": ("Float64", "independent", "continuous", None, None, "s", 6),
        "x": ("Float64", "input", "continuous", "exact", "1.5", "m", 0),
        "n": ("Int32", "input", "discrete", "exact", "3", None, 1),
        "on": ("Boolean", "parameter", "fixed", "exact", "true", None, 2),
        "k": ("Float64", "parameter", "tunable", "exact", "0.1", "1/s", 3),
        "y": ("Float64", "output", "continuous", "calculated", None, "m/s", 4),
        "c": ("Int32", "output", "discrete", "calculated", None, None, 5)}
    assert [u.variable.name for u in md.outputs] == ["y", "c"]
    assert [u.variable.name for u in md.initialUnknowns] == ["y", "c"]
    assert sorted(u.name for u in md.unitDefinitions) == ["1/s", "m", "m/s", "s"]


def test_a_variable_named_time_is_refused():
    with pytest.raises(ValueError, match="FMI 3.0 gives that name to the independent variable"):
        model_description("M", "{t}", "", [Row("time", 0, "input", "continuous", "Real", 0.0)])


def test_time_where_the_caller_puts_it(tmp_path):
    # a closed loop's time keeps its FMI 2.0 value reference 0, and its model name is not the
    # engine's identifier; a value reference of a variable is refused for time
    rows = [Row(r.name, r.value_reference + 1, r.causality, r.variability, r.type, r.start,
                r.description) for r in ROWS]
    (tmp_path / "modelDescription.xml").write_bytes(
        model_description("closed_loop", "{t}", "", rows, None, "", time_vr=0,
                          model_name="Loop"))
    assert validate_fmu(str(tmp_path)) == []
    md = read_model_description(str(tmp_path))
    assert md.modelName == "Loop" and md.coSimulation.modelIdentifier == "closed_loop"
    assert {v.name: v.valueReference for v in md.modelVariables} == {
        "time": 0, **{r.name: r.value_reference for r in rows}}
    with pytest.raises(ValueError, match="value reference 3 of 'time' is a variable's"):
        model_description("M", "{t}", "", rows, time_vr=3)


def test_build_description_lists_the_sources():
    text = build_description("M", ["fmi3_cs.c", "model.c"]).decode()
    assert '<BuildConfiguration modelIdentifier="M">' in text
    assert text.index('name="fmi3_cs.c"') < text.index('name="model.c"')
