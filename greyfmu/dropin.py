"""Turn the archive pythonfmu built into a drop-in FMU (build side; not embedded in the FMUs).

Given the archive's entries (name -> bytes), its model description and the slave's
requirements, `drop_in` returns new entries:

- ``binaries/linux64/<id>.so`` and ``binaries/win64/<id>.dll`` are the greyfmu loader
  (`greyfmu.loader`); pythonfmu's library moves next to it as ``pythonfmu-export.so``/``.dll``,
  and on Linux ``greyfmu-process.so`` joins them (what every loader in a process shares).
  Where there is no C compiler for a platform (cc; x86_64-w64-mingw32-gcc for win64) the
  pythonfmu library stays the binary, and the build says so once on stderr: that FMU then
  loads only in a host that already runs Python (fmpy, cosim; on Windows, python3.dll on PATH);
- ``resources/`` gets the loader's target check, the FMU's requirements, the path of the
  interpreter that built it (the loader's second choice) and ``greyfmu_guard.txt``, what the
  loader's guard checks every call against (`guard_text`);
- every Python module in ``resources/`` — the slave module, ``_slave``, ``_inprocess``, the greyfmu
  package, pythonfmu's run-time modules (no builder) — moves into one package whose name is
  private to the FMU's content, ``_greyfmu_<model>_<hash>`` (`privatise`), and every import of
  one of them names it there: the FMU adds no public name to a host's ``sys.modules``, so any
  number of our FMUs, of any release, other vendors' pythonfmu FMUs with the same model names
  and a host's own greyfmu or pythonfmu live in one process, each computing with its own code;
- ``documentation/`` gets ``index.html`` (`greyfmu.documentation`) and ``licenses/`` with the
  greyfmu and pythonfmu MIT notices;
- the model description gets ``version`` (the greyfmu version), ``license``, ``copyright``,
  no ``generationDateAndTime``, and a GUID derived from a hash of the model description and
  every embedded source (`stable_guid`), so the same sources give the same GUID and two
  builds the same modelDescription.xml.
"""

from __future__ import annotations

import hashlib
import sys
import uuid
from importlib.metadata import version
from pathlib import Path
from xml.etree import ElementTree

from greyfmu.documentation import index_html
from greyfmu.loader import PLATFORMS, PROCESS_LIBRARY, TARGET_CHECK, loader_binary, process_binary
from greyfmu.privatise import PYTHONFMU, PrivatiseError, privatise

LICENSES = Path(__file__).resolve().parent / "licenses"
LICENSE = "MIT"
COPYRIGHT = "Copyright (c) 2026 the greyfmu authors; embeds pythonfmu 0.7.0, Copyright (c) 2019-2020 NTNU and Safran SA"
BUILD_PYTHON = "resources/greyfmu_build_python.txt"
"""Machine-specific, so left out of the GUID's hash."""
GUARD = "resources/greyfmu_guard.txt"
"""What the loader's guard (greyfmu/loader/guard.h) checks calls against: `guard_text`.  It
holds the GUID, so it is left out of the GUID's hash (it is derived from the hashed model
description)."""
MAX_STEP_FACTOR = 1e4
"""The longest communication step the guard accepts, in DefaultExperiment stepSize units: a
slave computes every internal sample of a step, so h = 1e300 would never return."""
TYPE_LETTERS = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B", "String": "S"}
"""The fmi2Get/Set function family of each variable type (an Enumeration is an Integer)."""
TYPE_LETTERS3 = {"Float64": "R", "Int32": "I", "Int64": "L", "Enumeration": "L", "Boolean": "B", "String": "S"}
"""The fmi3Get/Set function family of each FMI 3.0 variable type (an Enumeration is an Int64)."""
TOKEN = {"2.0": "guid", "3.0": "instantiationToken"}
"""The attribute holding `stable_guid` in each FMI version's model description."""


class BuildError(RuntimeError):
    """An FMU could not be built or its model description is not what the FMI standard needs."""


def drop_in(entries: dict[str, bytes], root: ElementTree.Element, requirements: tuple[str, ...]) -> dict[str, bytes]:
    """The drop-in FMU's entries from pythonfmu's ``entries`` and the repaired model description ``root``;
    ``requirements``: the modules the FMU imports from the target Python (the slave's ``requirements``)."""
    model = root.get("modelName")
    identifier = root.find("CoSimulation").get("modelIdentifier")
    try:
        result = privatise(entries, model, PYTHONFMU, requirements)
    except PrivatiseError as error:
        raise BuildError(str(error)) from error
    loaders = []
    for platform in PLATFORMS:
        loader = loader_binary(platform)
        binary = f"binaries/{platform.folder}/{identifier}{platform.suffix}"
        if loader is not None and binary in result:
            result[f"binaries/{platform.folder}/{platform.pythonfmu_library}"] = result.pop(binary)
            result[binary] = loader
            loaders.append(platform.folder)
            if platform.folder == "linux64":
                result[f"binaries/linux64/{PROCESS_LIBRARY}"] = process_binary()
    return finish(result, root, requirements, tuple(loaders))


def finish(result: dict[str, bytes], root: ElementTree.Element, requirements: tuple[str, ...],
           loaders: tuple[str, ...]) -> dict[str, bytes]:
    """What every drop-in FMU gets once its code is private and its binaries in place (FMI 2.0 and
    3.0, ``root``'s fmiVersion): the loader's resources, the licences, version/licence/copyright,
    the stable GUID (FMI 3.0: instantiation token), the guard's file and documentation/index.html."""
    token = TOKEN[root.get("fmiVersion")]
    model = root.get("modelName")
    result["resources/greyfmu_target.py"] = TARGET_CHECK.read_bytes()
    result["resources/greyfmu_requirements.txt"] = "".join(f"{name}\n" for name in requirements).encode()
    result[BUILD_PYTHON] = f"{sys.executable}\n".encode()
    for notice in sorted(LICENSES.glob("*.txt")):
        result[f"documentation/licenses/{notice.name}"] = notice.read_bytes()
    _check_requirements_are_stated(root, model, requirements)
    root.set("version", version("greyfmu"))
    root.set("license", LICENSE)
    root.set("copyright", COPYRIGHT)
    root.attrib.pop("generationDateAndTime", None)
    ElementTree.indent(root)  # before the hash: it covers the text as written
    root.set(token, stable_guid(root, result, token))
    result[GUARD] = guard_text(root).encode()
    result["modelDescription.xml"] = ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True)
    result["documentation/index.html"] = index_html(root, requirements, loaders).encode()
    return result


def stable_guid(root: ElementTree.Element, entries: dict[str, bytes], token: str = "guid") -> str:
    """A GUID from the SHA-256 of the model description (its ``token`` attribute left out: FMI 2.0's
    guid, FMI 3.0's instantiationToken) and of
    every resource but the machine-specific `BUILD_PYTHON`, in name order."""
    digest = hashlib.sha256()
    described = {key: value for key, value in root.attrib.items() if key != token}
    digest.update(repr(sorted(described.items())).encode())
    for child in root:
        digest.update(ElementTree.tostring(child, encoding="UTF-8"))
    for name in sorted(entries):
        if name.startswith("resources/") and name not in (BUILD_PYTHON, GUARD):
            digest.update(name.encode() + b"\0" + hashlib.sha256(entries[name]).digest())
    return str(uuid.UUID(bytes=digest.digest()[:16], version=5))


def guard_text(root: ElementTree.Element) -> str:
    """`GUARD`'s text: ``guid G``, ``max_step H`` (`MAX_STEP_FACTOR` DefaultExperiment steps; 0:
    no bound but finiteness), then one ``variable VR TYPE CAUSALITY VARIABILITY INITIAL NAME``
    line per variable (TYPE one of `TYPE_LETTERS`' letters, FMI 3.0: `TYPE_LETTERS3`'; INITIAL as
    FMI 2.0 Table 2 and FMI 3.0 Table 19 resolve its default, ``none`` for inputs and the
    independent variable); FMI 3.0's instantiation token is the ``guid`` line."""
    experiment = root.find("DefaultExperiment")
    step = float(experiment.get("stepSize", "0")) if experiment is not None else 0.0
    lines = [f"guid {root.get(TOKEN[root.get('fmiVersion')])}", f"max_step {MAX_STEP_FACTOR * step!r}"]
    if root.get("fmiVersion") == "3.0":
        typed = [(variable, TYPE_LETTERS3[variable.tag]) for variable in root.find("ModelVariables")]
    else:
        typed = [(variable, TYPE_LETTERS[variable[0].tag]) for variable in root.findall("ModelVariables/ScalarVariable")]
    for variable, letter in typed:
        causality = variable.get("causality", "local")
        variability = variable.get("variability", "continuous")
        initial = variable.get("initial") or _default_initial(causality, variability)
        lines.append(f"variable {variable.get('valueReference')} {letter} {causality} "
                     f"{variability} {initial} {variable.get('name')}")
    return "".join(f"{line}\n" for line in lines)


def _default_initial(causality: str, variability: str) -> str:
    """FMI 2.0 §2.2.7 Table: the ``initial`` a variable has when it does not say."""
    if causality in ("input", "independent"):
        return "none"
    if causality == "parameter" or variability == "constant":
        return "exact"
    return "calculated"


def _check_requirements_are_stated(root: ElementTree.Element, model: str, requirements: tuple[str, ...]) -> None:
    description = root.get("description", "")
    unstated = [name for name in requirements if name not in description]
    if unstated:
        raise BuildError(f"{model}: the slave requires {', '.join(unstated)}, which its description does not name")
