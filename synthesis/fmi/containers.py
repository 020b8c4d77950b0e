"""Closed loops as one FMU: a plant and a controller in one closed-loop FMU, and SSP files.

* :func:`closed_loop_fmu` -- plant + controller composed into one FMU that ``fmpy simulate``
  runs directly at any output interval: fmpy's container-FMU support writes the archive (the
  variables, the components extracted in ``resources/``), :func:`into_engine` gives it the
  package's closed-loop engine (``synthesis/fmi/native/c/loop/closed_loop.c``) as its binary;
* :func:`write_ssp` -- an SSP 1.0 archive (SystemStructure.ssd + the two FMUs) of the same system,
  for tools that read SSP; it is checked against the SSP schema by ``fmpy.ssp.ssd.read_ssd``.
"""
from __future__ import annotations

import functools
import json
import shutil
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import attrs
from fmpy import read_model_description

from descent_fmus.synthesis.fmi.closed_loop import Wiring
from descent_fmus.synthesis.fmi.compose import add_units, rewrite_archive
from descent_fmus.synthesis.paths import require_fmu

__all__ = ["closed_loop_fmu", "into_engine", "engine_library", "write_ssp"]


def closed_loop_fmu(wiring: Wiring, plant_fmu: Path, controller_fmu: Path, dest: Path,
                    parameters: tuple = (), starts: bool = True, engine: bool = True) -> Path:
    """Compose plant and controller into one closed-loop FMU (see the module docstring).

    Parameters
    ----------
    wiring : Wiring
        Connections, communication step (= the container's fixed step) and exposed outputs.
    plant_fmu, controller_fmu : path-like
        Component FMUs (their file stems must equal their model identifiers).
    dest : path-like
        Output ``.fmu`` file.
    parameters : tuple of (str, str, str)
        (container name, "plant" | "controller", component variable) parameters to expose.
    starts : bool
        False: the exposed parameters carry no start value -- a container for evaluation only
        (``synthesis.fmi.container_loop``), whose reset then leaves them at the components' own defaults
        instead of setting each one again (fmpy's container sets every start value on reset).
    engine : bool
        False: keep fmpy's container binary (fixed step: output intervals must be multiples
        of the wiring's step) -- the former closed-loop FMU, kept as a reference for tests.
    """
    from fmpy.container_fmu.config import Configuration

    plant_fmu, controller_fmu, dest = require_fmu(plant_fmu), require_fmu(controller_fmu), Path(dest)
    parts = _Components(plant_fmu, controller_fmu)
    parameters = tuple(parameters)
    if (wiring.to_controller and "sample_period" in parts.cvars["controller"]
            and "sample_period" not in {c for c, _, _ in parameters}):
        # the controller's sample period is a parameter of the closed loop (the engine's T)
        parameters += (("sample_period", "controller", "sample_period"),)
    variables, mappings, outputs = _container_variables(wiring, parts, parameters, starts)
    connections = _connections(wiring, parts)
    md = _container_description(wiring, parts, variables, outputs)
    config = Configuration(parallelDoStep=False, modelDescription=md,
                           components=[parts.comps["plant"], parts.comps["controller"]],
                           connections=connections, variableMappings=mappings)
    dest.parent.mkdir(parents=True, exist_ok=True)
    return _create_container(config, parts, wiring.name, dest, engine)


class _Components:
    """The two components of a container FMU (roles ``"plant"`` and ``"controller"``): their
    model descriptions ``mds``, fmpy ``Component`` records ``comps`` and variables by name
    ``cvars``."""

    def __init__(self, plant_fmu: Path, controller_fmu: Path):
        from fmpy.container_fmu.config import Component
        self.paths = {"plant": plant_fmu, "controller": controller_fmu}
        self.mds = {role: read_model_description(str(path)) for role, path in self.paths.items()}
        self.comps = {role: Component(name=role, filename=path, modelDescription=self.mds[role])
                      for role, path in self.paths.items()}
        self.cvars = {role: {v.name: v for v in md.modelVariables}
                      for role, md in self.mds.items()}

    def var(self, role: str, name: str):
        """The variable ``name`` of the component ``role``.

        Raises
        ------
        KeyError
            The component has no such variable (the message names the model).
        """
        try:
            return self.cvars[role][name]
        except KeyError:
            raise KeyError(f"{self.mds[role].modelName} has no variable {name!r}") from None


def _container_variables(wiring: Wiring, parts: _Components, parameters: tuple,
                         starts: bool) -> tuple:
    """The container's variables: ``time``, the exposed parameters (the controller's
    ``sample_period`` starts at the wiring's step; the others at the component's start value,
    or none if not ``starts``) and the wiring's exposed outputs.  Returns the variables, their
    mappings onto the components' variables and the outputs (``Unknown`` records)."""
    from fmpy.model_description import ModelVariable, Unknown

    variables = [ModelVariable(type="Real", variability="continuous", causality="independent",
                               name="time", description="time [s]")]
    mappings, outputs = {}, []
    for cname, role, vname in parameters:
        src = parts.var(role, vname)
        start = (repr(float(wiring.step)) if (role, vname) == ("controller", "sample_period")
                 else src.start if starts else None)
        v = ModelVariable(type=src.type, variability="fixed", causality="parameter",
                          initial="exact", name=cname, start=start,
                          description=src.description)
        variables.append(v)
        mappings[v] = [(parts.comps[role], src)]
    for cname, role, vname in wiring.exposed:
        src = parts.var(role, vname)
        v = ModelVariable(type=src.type,
                          variability="discrete" if src.type == "Integer" else "continuous",
                          causality="output", initial="calculated", name=cname,
                          description=src.description)
        variables.append(v)
        mappings[v] = [(parts.comps[role], src)]
        outputs.append(Unknown(variable=v))
    return variables, mappings, outputs


def _connections(wiring: Wiring, parts: _Components) -> list:
    """The wiring's connections, plant -> controller first: the controller then reads y(t) when
    u is copied, the master algorithm of :mod:`synthesis.fmi.closed_loop`."""
    from fmpy.container_fmu.config import Connection

    def conn(src_role, a, dst_role, b):
        # fmpy 0.3.32 writes a connection's type verbatim but its container reads FMI 3 type
        # names (Float64, Int32): hand it connectors that carry those names.
        va, vb = parts.var(src_role, a), parts.var(dst_role, b)
        kind = {"Real": "Float64", "Integer": "Int32"}.get(va.type, va.type)
        return Connection(parts.comps[src_role], [attrs.evolve(va, type=kind)],
                          parts.comps[dst_role], [attrs.evolve(vb, type=kind)])

    connections = [conn("plant", a, "controller", b) for a, b in wiring.to_controller]
    connections += [conn("controller", a, "plant", b) for a, b in wiring.to_plant]
    return connections


def _container_description(wiring: Wiring, parts: _Components, variables: list,
                           outputs: list):
    """The container's model description: fixed internal step = the wiring's step, the
    default experiment of the wiring."""
    from fmpy.model_description import (CoSimulation, DefaultExperiment, ModelDescription,
                                        Unknown)
    mds = parts.mds
    return ModelDescription(
        fmiVersion="2.0", modelName=wiring.name, instantiationToken=f"{{{uuid.uuid4()}}}",
        description=wiring.description or f"{mds['plant'].modelName} + "
                                          f"{mds['controller'].modelName} in closed loop",
        generationTool="descent-fmus (fmpy container FMU)",
        variableNamingConvention="structured",
        defaultExperiment=DefaultExperiment(startTime="0", stopTime=repr(wiring.stop_time),
                                            stepSize=repr(wiring.step)),
        coSimulation=CoSimulation(modelIdentifier="container_fmu",
                                  fixedInternalStepSize=wiring.step),
        modelVariables=variables, outputs=outputs,
        initialUnknowns=[Unknown(variable=u.variable) for u in outputs])


def _create_container(config, parts: _Components, name: str, dest: Path,
                      engine: bool = True) -> Path:
    """Write the container FMU of ``config`` to ``dest``, the components' units in its
    variables' descriptions: the package's engine as its binary where it can be built
    (:func:`_engine_container`), else fmpy's container binary (fmpy writes the archive)."""
    from fmpy.container_fmu.cli import create_container_fmu

    with tempfile.TemporaryDirectory(prefix="descent_container_") as tmp:
        # the container resolves components by file stem: copy them under their identifiers
        for role, path in parts.paths.items():
            ident = parts.mds[role].coSimulation.modelIdentifier
            target = Path(tmp) / "src" / f"{ident}.fmu"
            target.parent.mkdir(exist_ok=True)
            shutil.copy(path, target)
            parts.comps[role].filename = target
        lib = _engine_library() if engine else None
        if lib is not None:
            return _engine_container(config, parts, lib, Path(tmp), dest)
        work = Path(tmp) / "work"
        work.mkdir()
        out = Path(tmp) / f"{name}.fmu"
        create_container_fmu(config, work, out)
        add_units(out)      # the variables' descriptions carry the components' units
        shutil.move(str(out), dest)
    return dest


def _engine_container(config, parts: _Components, lib: bytes, tmp: Path, dest: Path) -> Path:
    """The closed-loop FMU of fmpy's container ``config`` with the engine's library ``lib``
    as its binary, written in one pass: the model description and configuration as fmpy's
    container writer makes them (:func:`into_engine` then gives the same archive), the
    components' members copied compressed under ``resources/<stem>/``
    (:mod:`synthesis.fmi.native.builders.archives`: no member is compressed twice; those of
    a component's archive that stores them are deflated once per process and file, read from the
    component's own path in ``parts``)."""
    from fmpy.container_fmu import write_configuration
    from fmpy.model_description import write_model_description

    from descent_fmus.synthesis.fmi.native.builders.archives import (
        compressed_members, copied, deflated, write_archive)
    from descent_fmus.synthesis.fmi.description.units import units_into_model_description
    md = config.modelDescription           # as fmpy's create_container_fmu numbers them
    md.coSimulation.modelIdentifier = "container_fmu"
    for i, variable in enumerate(md.modelVariables):
        variable.valueReference = i
    write_model_description(md, tmp / "modelDescription.xml")
    write_configuration(config, tmp / "container.json")
    root = ET.parse(tmp / "modelDescription.xml").getroot()
    units_into_model_description(root)
    xml, text = _engine_description(json.loads((tmp / "container.json").read_text()), root)
    entries = [deflated("modelDescription.xml", xml)]
    for comp in config.components:
        stem = Path(comp.filename).stem
        entries += [copied(f"resources/{stem}/{info.filename}", info, data)
                    for info, data in compressed_members(parts.paths[comp.name])]
    entries += [deflated("binaries/linux64/closed_loop.so", lib),
                deflated("resources/loop.txt", text)]
    return write_archive(dest, entries)


def engine_library(fmi_version: int = 2, compiler: str | None = None) -> Path:
    """The closed-loop engine (``synthesis/fmi/native/c/loop/``) compiled for this machine, once
    (:func:`.build.cached_library`): its FMI 2.0 face, or with ``fmi_version=3`` the same
    sources under the FMI 3.0 wrapper (``c/fmi3/fmi3_loop.c``: ``fmi3_cs.c`` compiled over the
    engine, as over ``fmi2_cs.c`` for a native FMU).

    Raises
    ------
    CompilerNotFoundError, NativeBuildError
    """
    from descent_fmus.synthesis.fmi.native.builders.build import C_ROOT, cached_library
    loop = C_ROOT / "loop"
    files = (loop / "closed_loop.c", loop / "loop_values.c")
    headers = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h", loop / "loop.h")
    if fmi_version == 3:          # fmi3_loop.c includes the engine's files: they are headers
        files, headers = ("fmi3_loop.c",), headers + files + (
            "fmi3_cs.c", "fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
    elif fmi_version != 2:
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    return cached_library("closed-loop" if fmi_version == 2 else "closed-loop-fmi3", files,
                          headers, compiler, libraries=("m", "dl"))


@functools.cache
def _engine_library() -> bytes | None:
    """The engine's FMI 2.0 library (:func:`engine_library`), once per process, or None where
    it cannot be built (no C compiler, not linux64)."""
    from descent_fmus.synthesis.fmi.native.builders.build import (NativeBuildError,
                                                                  find_compiler, platform_folder)
    if platform_folder() != ("linux64", ".so") or find_compiler() is None:
        return None
    try:
        return engine_library().read_bytes()
    except NativeBuildError:
        return None


#: fmpy's container type names -> the engine's (resources/loop.txt)
_TYPES = {"Float64": "R", "Real": "R", "Int32": "I", "Integer": "I", "Boolean": "B"}


def _engine_config(config: dict, root: ET.Element) -> str:
    """The engine's ``resources/loop.txt`` of fmpy's container configuration ``config``
    (``resources/container.json``) and model description ``root`` (value references: the
    container's variables in order, 0 the time)."""
    lines = [f"name {root.get('modelName')}", f"period {float(config['fixedStepSize'])!r}"]
    for comp in config["components"]:
        lines.append(f"component {comp['name']} {comp['path']} {comp['modelIdentifier']} "
                     f"{comp['instantiationToken']}")
    svs = [sv for sv in root.iter("ScalarVariable") if sv.get("causality") != "independent"]
    if len(svs) != len(config["variables"]):
        raise ValueError("the container's variables do not match its model description")
    for sv, var in zip(svs, config["variables"]):
        (comp, cvr), = var["mappings"]
        kind = "p" if sv.get("causality") == "parameter" else "o"
        start = (var.get("start") or [None])[0]
        start = "" if start is None else f" {str(start).lower()}"
        lines.append(f"var {sv.get('valueReference')} {_TYPES[var['variableType']]} {comp} "
                     f"{cvr} {kind}{start}")
        if sv.get("name") == "sample_period":
            lines.append(f"periodvar {sv.get('valueReference')}")
    for c in config["connections"]:
        for a, b in zip(c["srcValueReferences"], c["dstValueReferences"]):
            lines.append(f"conn {_TYPES[c['variableType']]} {c['srcComponent']} {a} "
                         f"{c['dstComponent']} {b}")
    return "\n".join(lines) + "\n"


def into_engine(fmu: Path) -> Path:
    """Make an fmpy container FMU a closed-loop FMU of the package's engine (in place).

    Its binary becomes ``closed_loop.c`` compiled here (model identifier ``closed_loop``), which
    loads the two component FMUs fmpy extracted into ``resources/`` and accepts any
    communication step: the controller samples at the loop's period (``sample_period``) with a
    zero-order hold in between, the plant steps to the next sample or the end of the host's
    step.  Variables, start values and units stay as fmpy wrote them.  Without a C compiler
    (or off linux64) the FMU stays fmpy's container.
    """
    lib = _engine_library()
    if lib is None:
        return fmu
    fmu = Path(fmu)
    with zipfile.ZipFile(fmu) as z:
        xml, text = _engine_description(json.loads(z.read("resources/container.json")),
                                        ET.fromstring(z.read("modelDescription.xml")))

    def edit(item, data):
        if item.filename.startswith("binaries/") or item.filename in (
                "resources/container.json", "Container.zip"):
            return []
        return [(item, xml if item.filename == "modelDescription.xml" else data)]
    return rewrite_archive(fmu, fmu, edit, extra=[
        ("binaries/linux64/closed_loop.so", lib), ("resources/loop.txt", text)])


def _engine_description(config: dict, root: ET.Element) -> tuple:
    """The engine's model description (``root`` of fmpy's container, edited in place) and its
    ``resources/loop.txt``, from fmpy's container configuration ``config``: ``(xml, text)``
    as bytes."""
    text = _engine_config(config, root).encode()
    cs = root.find("CoSimulation")
    cs.attrib.clear()
    cs.attrib.update({"modelIdentifier": "closed_loop", "canHandleVariableCommunicationStepSize":
                      "true", "canInterpolateInputs": "false", "canBeInstantiatedOnlyOncePerProcess":
                      "false"})
    root.set("generationTool", "descent-fmus (closed-loop engine)")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True), text


_SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
_SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"


def write_ssp(wiring: Wiring, plant_fmu: Path, controller_fmu: Path, dest: Path) -> Path:
    """Write an SSP 1.0 archive of the closed loop (SystemStructure.ssd + resources/*.fmu)."""
    plant_fmu, controller_fmu, dest = require_fmu(plant_fmu), require_fmu(controller_fmu), Path(dest)
    ET.register_namespace("ssd", _SSD_NS)
    ET.register_namespace("ssc", _SSC_NS)
    q = lambda ns, tag: f"{{{ns}}}{tag}"  # noqa: E731
    root = ET.Element(q(_SSD_NS, "SystemStructureDescription"),
                      {"version": "1.0", "name": wiring.name,
                       "generationTool": "descent-fmus"})
    system = ET.SubElement(root, q(_SSD_NS, "System"), {"name": wiring.name})
    if wiring.description:
        system.set("description", wiring.description)
    elements = ET.SubElement(system, q(_SSD_NS, "Elements"))
    conns = ET.SubElement(system, q(_SSD_NS, "Connections"))
    used = {"plant": set(a for a, _ in wiring.to_controller) | set(b for _, b in wiring.to_plant),
            "controller": set(b for _, b in wiring.to_controller) |
                          set(a for a, _ in wiring.to_plant)}
    used["plant"] |= {v for _, r, v in wiring.exposed if r == "plant"}
    from descent_fmus.synthesis.fmi.description.units import base_unit
    units = set()
    for role, path in (("plant", plant_fmu), ("controller", controller_fmu)):
        md = read_model_description(str(path))
        comp = ET.SubElement(elements, q(_SSD_NS, "Component"),
                             {"name": role, "type": "application/x-fmu-sharedlibrary",
                              "source": f"resources/{path.name}"})
        cons = ET.SubElement(comp, q(_SSD_NS, "Connectors"))
        for v in md.modelVariables:
            if v.name in used[role]:
                kind = {"input": "input", "output": "output"}.get(v.causality, "parameter")
                c = ET.SubElement(cons, q(_SSD_NS, "Connector"), {"name": v.name, "kind": kind})
                t = ET.SubElement(c, q(_SSC_NS, v.type))
                # SSP units need SI exponents: a unit FMI 2.0 cannot state stays off
                if v.type == "Real" and v.unit and base_unit(v.unit) is not None:
                    t.set("unit", v.unit)
                    units.add(v.unit)
    for a, b in wiring.to_controller:
        ET.SubElement(conns, q(_SSD_NS, "Connection"), {"startElement": "plant",
                      "startConnector": a, "endElement": "controller", "endConnector": b})
    for a, b in wiring.to_plant:
        ET.SubElement(conns, q(_SSD_NS, "Connection"), {"startElement": "controller",
                      "startConnector": a, "endElement": "plant", "endConnector": b})
    if units:                      # ssd:Units comes between ssd:System and DefaultExperiment
        ud = ET.SubElement(root, q(_SSD_NS, "Units"))
        for name in sorted(units):
            exps, factor = base_unit(name)
            u = ET.SubElement(ud, q(_SSC_NS, "Unit"), {"name": name})
            bu = {b: str(e) for b, e in exps.items()}
            if factor != 1.0:
                bu["factor"] = repr(factor)
            ET.SubElement(u, q(_SSC_NS, "BaseUnit"), bu)
    ET.SubElement(root, q(_SSD_NS, "DefaultExperiment"),
                  {"startTime": "0", "stopTime": repr(wiring.stop_time)})
    # the plant FMU deflated once per process (its builder may store its members), the law
    # FMU as it is (compressed already: one per law)
    from descent_fmus.synthesis.fmi.native.builders.archives import (
        compressed_file, deflated, stored, write_archive)
    return write_archive(dest, [
        deflated("SystemStructure.ssd", ET.tostring(root, encoding="UTF-8", xml_declaration=True)),
        compressed_file(f"resources/{plant_fmu.name}", plant_fmu),
        stored(f"resources/{controller_fmu.name}", controller_fmu.read_bytes())])
