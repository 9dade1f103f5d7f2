"""The FMI 3.0 sibling of a greyfmu FMU (build side; not embedded in the FMUs).

``greyfmu build PID3`` (or ``--fmi 3``) makes ``PID3.fmu``, FMI 3.0 Co-Simulation, from the same
``fmus/PID.py`` as ``PID.fmu``: pythonfmu builds the archive as for FMI 2.0 (``fmus/fmi3/_slave3.py``
added to its resources), then

- `model_description3` writes the FMI 3.0 model description from the repaired FMI 2.0 one: the
  same variables, value references, units, min/max, starts and descriptions; Real -> Float64,
  Integer -> Int32, a mode parameter (an ``IntEnum`` start) -> an Enumeration whose
  ``EnumerationType`` describes the IntEnum's members; the independent variable ``time``
  FMI 3.0 requires (value reference: the first free one); ``ModelStructure/Output`` with the
  dependencies as value references; modelName and modelIdentifier ``<Name>3``;
- `drop_in3` makes it a drop-in FMU as `greyfmu.dropin` does for FMI 2.0: the code under the
  FMU's private package, whose ``_slave3`` module is pythonfmu3's slave module (it answers with
  the FMI 3.0 class of the FMI 2.0 slave, fmus/fmi3/_slave3.py); greyfmu's FMI 3.0 loader
  (greyfmu/loader/fmi3_loader.c) as ``binaries/x86_64-linux/<Name>3.so`` and
  ``binaries/x86_64-windows/<Name>3.dll``, pythonfmu3 0.3.4's library beside it as
  ``pythonfmu3-export.so``/``.dll``; the stable instantiation token, the guard's file and
  ``documentation/`` (`greyfmu.dropin.finish`).

The FMU's name: ``<Name>3.fmu`` next to ``<Name>.fmu`` in one folder, so an SSD or a user picks a
version by file name (``resources/PID3.fmu``), the FMU provider serves both by name, and the
binaries of the two siblings have different names (``PID.so``, ``PID3.so``) in a host that loads both.
"""

from __future__ import annotations

import ast
import inspect
import textwrap
from enum import IntEnum
from importlib.metadata import PackageNotFoundError, distribution
from xml.etree import ElementTree

from greyfmu.dropin import BuildError, finish
from greyfmu.loader import PLATFORMS, PROCESS_LIBRARY, loader_binary, process_binary
from greyfmu.privatise import PYTHONFMU, PrivatiseError, privatise

SUFFIX = "3"
"""An FMI 3.0 FMU is named like its FMI 2.0 sibling with this suffix: PID -> PID3."""
SLAVE_MODULE3 = "_slave3"
"""pythonfmu3's slave module in an FMI 3.0 FMU (fmus/fmi3/_slave3.py)."""
TYPES3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
CO_SIMULATION3 = {"needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
                  "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
                  "canHandleVariableCommunicationStepSize": "true"}
"""The FMI 3.0 Co-Simulation capabilities: those of the FMI 2.0 sibling (fmus/_slave.py)."""


def fmi3_name(name: str) -> str:
    """The FMI 3.0 sibling's name of the FMU ``name``."""
    return name + SUFFIX


def model_description3(root: ElementTree.Element, choices: dict[str, type[IntEnum]]) -> ElementTree.Element:
    """The FMI 3.0 model description of the FMU whose repaired FMI 2.0 one is ``root`` (see the
    module docstring); ``choices``: parameter name -> the IntEnum of each mode parameter."""
    model = root.get("modelName")
    name3 = fmi3_name(model)
    attributes = {key: value for key, value in root.attrib.items()
                  if key not in ("fmiVersion", "guid", "modelName", "generationDateAndTime")}
    attributes["description"] = f"FMI 3.0 build of {model}.fmu, the same model: " + attributes.get("description", "")
    attributes["generationTool"] = f"greyfmu ({root.get('generationTool')} slave, PythonFMU3 0.3.4 run-time)"
    description3 = ElementTree.Element("fmiModelDescription", {"fmiVersion": "3.0", "modelName": name3,
                                                              "instantiationToken": "", **attributes})
    ElementTree.SubElement(description3, "CoSimulation", {"modelIdentifier": name3, **CO_SIMULATION3})
    units = root.find("UnitDefinitions")
    units = ElementTree.fromstring(ElementTree.tostring(units)) if units is not None else \
        ElementTree.Element("UnitDefinitions")
    if units.find("Unit[@name='s']") is None:  # time's
        ElementTree.SubElement(ElementTree.SubElement(units, "Unit", name="s"), "BaseUnit", s="1")
    description3.append(units)
    if choices:
        types = ElementTree.SubElement(description3, "TypeDefinitions")
        for enumeration in sorted({choice for choice in choices.values()}, key=lambda e: e.__name__):
            text, members = _enumeration_items(model, enumeration)
            node = ElementTree.SubElement(types, "EnumerationType", name=enumeration.__name__, description=text)
            for member, item in members.items():
                ElementTree.SubElement(node, "Item", name=member.name, value=str(member.value), description=item)
    categories = ElementTree.SubElement(description3, "LogCategories")
    for category in root.iter("Category"):
        ElementTree.SubElement(categories, "Category", name=category.get("name"),
                               description=category.get("description", "").replace("fmi2", "fmi3"))
    experiment = root.find("DefaultExperiment")
    if experiment is not None:
        ElementTree.SubElement(description3, "DefaultExperiment", dict(experiment.attrib))
    variables = root.findall("ModelVariables/ScalarVariable")
    variables3 = ElementTree.SubElement(description3, "ModelVariables")
    time_vr = 1 + max((int(variable.get("valueReference")) for variable in variables), default=-1)
    ElementTree.SubElement(variables3, "Float64", name="time", valueReference=str(time_vr), causality="independent",
                           variability="continuous", description="Simulation time", unit="s")
    for variable in variables:
        kind = variable[0]
        name = variable.get("name")
        tag = "Enumeration" if name in choices else TYPES3[kind.tag]
        attributes = {key: variable.get(key) for key in ("name", "valueReference", "description", "causality",
                                                         "variability", "initial") if variable.get(key) is not None}
        if name in choices:
            attributes["declaredType"] = choices[name].__name__
        attributes.update(kind.attrib)
        ElementTree.SubElement(variables3, tag, attributes)
    vr_of_index = {str(position): variable.get("valueReference") for position, variable in enumerate(variables, 1)}
    structure = ElementTree.SubElement(description3, "ModelStructure")
    for unknown in root.findall("ModelStructure/Outputs/Unknown"):
        dependencies = " ".join(vr_of_index[index] for index in unknown.get("dependencies", "").split())
        ElementTree.SubElement(structure, "Output", valueReference=vr_of_index[unknown.get("index")],
                               dependencies=dependencies)
    return description3


def drop_in3(entries: dict[str, bytes], root3: ElementTree.Element, model: str,
             requirements: tuple[str, ...]) -> dict[str, bytes]:
    """The FMI 3.0 drop-in FMU's entries from pythonfmu's ``entries`` of the FMI 2.0 slave ``model``
    and the FMI 3.0 model description ``root3`` (see the module docstring)."""
    try:
        result = privatise(entries, model, PYTHONFMU, requirements)
    except PrivatiseError as error:
        raise BuildError(str(error)) from error
    package = result["resources/slavemodule.txt"].decode().partition(".")[0]
    del result[f"resources/{package}.{model}.py"]  # pythonfmu 0.7.0's stub: pythonfmu3 reads another
    if f"resources/{package}/{SLAVE_MODULE3}.py" not in result:
        raise BuildError(f"{model}: the FMU has no {SLAVE_MODULE3}.py to be pythonfmu3's slave module")
    result["resources/slavemodule.txt"] = f"{package}.{SLAVE_MODULE3}".encode()
    result[f"resources/{package}.{SLAVE_MODULE3}.py"] = (
        f"# pythonfmu3 reads the name of the slave class here and asks {package}.{SLAVE_MODULE3} for it:\n"
        f"# the FMI 3.0 class of the slave {model} (fmus/fmi3/_slave3.py).\n"
        f"class {model}(Fmi3Slave):\n    pass\n").encode()
    identifier = root3.find("CoSimulation").get("modelIdentifier")
    result = {name: data for name, data in result.items() if not name.startswith("binaries/")}
    loaders = []
    for platform in PLATFORMS:
        library = _pythonfmu3_library(platform.folder3, platform.suffix)
        loader = loader_binary(platform, fmi=3)
        folder = f"binaries/{platform.folder3}"
        if loader is None:
            result[f"{folder}/{identifier}{platform.suffix}"] = library
            continue
        result[f"{folder}/{identifier}{platform.suffix}"] = loader
        result[f"{folder}/{platform.pythonfmu3_library}"] = library
        loaders.append(platform.folder3)
        if platform.folder == "linux64":
            result[f"{folder}/{PROCESS_LIBRARY}"] = process_binary()
    return finish(result, root3, requirements, tuple(loaders))


def _pythonfmu3_library(folder: str, suffix: str) -> bytes:
    """pythonfmu3's FMI 3.0 library for a platform folder, from the installed distribution's files
    (not from an imported pythonfmu3, which another vendor's FMU run in this process may shadow)."""
    name = "libpythonfmu-export.so" if suffix == ".so" else "pythonfmu-export.dll"
    try:
        path = distribution("pythonfmu3").locate_file(f"pythonfmu3/resources/binaries/{folder}/{name}")
    except PackageNotFoundError as error:
        raise BuildError("FMI 3.0 FMUs need pythonfmu3 0.3.4 installed (pip install pythonfmu3==0.3.4)") from error
    if not path.is_file():
        raise BuildError(f"pythonfmu3 has no {folder} library ({path})")
    return path.read_bytes()


def _enumeration_items(model: str, enumeration: type[IntEnum]) -> tuple[str, dict[IntEnum, str]]:
    """An IntEnum's description (its docstring's first line) and each member's (the docstring
    under it, `_member_descriptions`); BuildError naming what is undocumented."""
    where = f"IntEnum {enumeration.__name__} ({enumeration.__module__})"
    if not enumeration.__doc__:
        raise BuildError(f"{model}: {where} has no docstring to describe the Enumeration type")
    descriptions = _member_descriptions(enumeration)
    undocumented = [member.name for member in enumeration if member.name not in descriptions]
    if undocumented:
        raise BuildError(f"{model}: members {undocumented} of {where} have no docstring under them to describe "
                         "the Enumeration items")
    return enumeration.__doc__.strip().splitlines()[0], {member: descriptions[member.name] for member in enumeration}


def _member_descriptions(enumeration: type[IntEnum]) -> dict[str, str]:
    """Member name -> the string literal right under its assignment in the class body (an
    attribute docstring), whitespace collapsed."""
    body = ast.parse(textwrap.dedent(inspect.getsource(enumeration))).body[0].body
    descriptions = {}
    for statement, following in zip(body, body[1:]):
        if (isinstance(statement, ast.Assign) and len(statement.targets) == 1
                and isinstance(statement.targets[0], ast.Name) and isinstance(following, ast.Expr)
                and isinstance(following.value, ast.Constant) and isinstance(following.value.value, str)):
            descriptions[statement.targets[0].id] = " ".join(following.value.value.split())
    return descriptions
