"""The FMI 3.0 model description and build description of a native FMU.

The same variable table as the FMI 2.0 description (the builder's ``Variable`` list, turned into
:class:`Row` by :mod:`synthesis.fmi.native.builders.fmi3`), written in FMI 3.0 terms: Real ->
``Float64``, Integer -> ``Int32``, Boolean -> ``Boolean``; the GUID as ``instantiationToken``;
``<Output>`` and ``<InitialUnknown>`` by value reference; the unit of every Float64 from its
description's bracket (:mod:`.units`, as for FMI 2.0); and the independent variable ``time``
that FMI 3.0 requires, after every model variable (or where the FMI 2.0 FMU has its own: a
closed loop's, value reference 0).
"""
from __future__ import annotations

from dataclasses import dataclass
from xml.etree import ElementTree as ET

from descent_fmus.synthesis.fmi.description.units import unit_definitions, unit_of_description

__all__ = ["Row", "FMI3_TYPES", "model_description", "build_description", "TIME"]

#: FMI 2.0 type -> FMI 3.0 element.
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
#: Name and description of the independent variable.
TIME = ("time", "simulation time [s]")


@dataclass(frozen=True)
class Row:
    """One variable of the description."""

    name: str
    value_reference: int
    causality: str            #: "input", "output" or "parameter"
    variability: str          #: "continuous", "discrete", "fixed" or "tunable"
    type: str                 #: "Real", "Integer" or "Boolean"
    start: object = None      #: None for an output (initial="calculated")
    description: str = ""


def _start(row: Row) -> str:
    if row.type == "Real":
        return repr(float(row.start))
    if row.type == "Boolean":
        return "true" if row.start else "false"
    return str(int(row.start))


def _variable(parent: ET.Element, row: Row) -> set:
    """Append ``row``'s element; return its unit (a set of at most one name)."""
    attrs = {"name": row.name, "valueReference": str(row.value_reference),
             "description": row.description, "causality": row.causality,
             "variability": row.variability}
    if row.type != "Real" and row.variability == "continuous":
        attrs["variability"] = "discrete"
    if row.causality == "output":
        attrs["initial"] = "calculated"
    elif row.causality == "parameter":
        attrs["initial"] = "exact"
    if row.start is not None and row.causality != "output":
        attrs["start"] = _start(row)
    unit = unit_of_description(row.description) if row.type == "Real" else None
    if unit is not None:
        attrs["unit"] = unit
    ET.SubElement(parent, FMI3_TYPES[row.type], attrs)
    return {unit} if unit is not None else set()


def model_description(identifier: str, token: str, description: str, rows,
                      experiment: dict | None = None, generation_tool: str = "",
                      time_vr: int | None = None, model_name: str | None = None) -> bytes:
    """``modelDescription.xml`` (FMI 3.0, co-simulation) of ``rows`` (value references unique;
    ``time`` gets ``time_vr``, by default the one after every row's); the model's name is
    ``model_name``, by default its identifier."""
    rows = list(rows)
    if any(r.name == TIME[0] for r in rows):
        raise ValueError(f"a variable is named {TIME[0]!r}: FMI 3.0 gives that name to the "
                         f"independent variable")
    if time_vr is None:
        time_vr = max((r.value_reference for r in rows), default=-1) + 1
    elif any(r.value_reference == time_vr for r in rows):
        raise ValueError(f"value reference {time_vr} of {TIME[0]!r} is a variable's")
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": model_name or identifier, "instantiationToken": token,
        "description": description, "generationTool": generation_tool,
        "variableNamingConvention": "structured"})
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "needsExecutionTool": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "canGetAndSetFMUState": "false",
        "canSerializeFMUState": "false", "providesDirectionalDerivatives": "false",
        "providesAdjointDerivatives": "false", "providesPerElementDependencies": "false",
        "canHandleVariableCommunicationStepSize": "true", "maxOutputDerivativeOrder": "0",
        "providesIntermediateUpdate": "false", "mightReturnEarlyFromDoStep": "false",
        "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
        "providesEvaluateDiscreteStates": "false"})
    logs = ET.SubElement(root, "LogCategories")
    ET.SubElement(logs, "Category", {"name": "logStatusError", "description": "errors (invalid "
                                     "parameters, calls in the wrong state)"})
    if experiment:
        ET.SubElement(root, "DefaultExperiment",
                      {k: repr(float(v)) for k, v in experiment.items()})
    variables = ET.SubElement(root, "ModelVariables")
    units = _variable(variables, Row(TIME[0], time_vr, "independent", "continuous", "Real",
                                     None, TIME[1]))
    for row in rows:
        units |= _variable(variables, row)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [r for r in rows if r.causality == "output"]
    for tag in ("Output", "InitialUnknown"):
        for r in outputs:
            ET.SubElement(structure, tag, {"valueReference": str(r.value_reference)})
    if units:
        root.insert(1, unit_definitions(units))   # after <CoSimulation>, as the schema orders
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def build_description(identifier: str, c_files) -> bytes:
    """``sources/buildDescription.xml`` (FMI 3.0): the C files to compile into ``identifier``."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    config = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": identifier})
    files = ET.SubElement(config, "SourceFileSet", {"language": "C99"})
    for name in c_files:
        ET.SubElement(files, "SourceFile", {"name": name})
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
