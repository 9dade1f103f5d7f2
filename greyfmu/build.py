"""Build the FMUs of ``fmus/`` with pythonfmu and repair what pythonfmu 0.7.0 writes wrong.

Each ``fmus/<Name>.py`` becomes ``<out_dir>/<Name>.fmu`` (FMI 2.0 Co-Simulation) with the
``greyfmu`` package and ``fmus/_slave.py`` embedded as resources; each ``fmus/fmi3/<Name>.py``
becomes an FMI 3.0 Co-Simulation FMU built with pythonfmu3, with ``fmus/fmi3/_slave3.py``.  The archive's
modelDescription.xml is then post-processed:

- every output must have ``initial="exact"`` and a start value (the build fails otherwise);
- ``ModelStructure/Outputs/Unknown`` gets ``dependencies`` from the slave class's
  ``output_dependencies`` (pythonfmu omits it, which means "depends on every input");
- ``UnitDefinitions`` declares every unit the variables use;
- then `greyfmu.dropin` makes it a drop-in FMU: greyfmu's loader as the linux64 binary, a
  stable GUID, version/licence/copyright, ``documentation/`` with index.html and the licences;
- last, `greyfmu.lsref` adds the FMI-LS-REF reference experiment (``extra/``), run on the FMU built.

The embedded greyfmu package leaves out what only builds FMUs (`BUILD_ONLY`).

``dependenciesKind`` is not written: absent, it means "dependent", which is all the
slaves can promise in general.
"""

from __future__ import annotations

import ast
import inspect
import os
import shutil
import textwrap
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterable
from enum import IntEnum
from pathlib import Path
from xml.etree import ElementTree

from pythonfmu.builder import FmuBuilder, get_model_class

from greyfmu.dropin import BuildError, drop_in
from greyfmu.loader import PLATFORMS, compiler
from greyfmu.lsref import with_reference

PACKAGE_DIR = Path(__file__).resolve().parent
REPOSITORY_ROOT = PACKAGE_DIR.parent
FMU_SOURCES = REPOSITORY_ROOT / "fmus"
SLAVE_BASE = FMU_SOURCES / "_slave.py"
FMI3_SOURCES = FMU_SOURCES / "fmi3"
SLAVE_BASE3 = FMI3_SOURCES / "_slave3.py"
DEFAULT_OUT_DIR = REPOSITORY_ROOT / "build" / "fmus"
BUILD_ONLY = ("build.py", "cli.py", "dropin.py", "documentation.py", "lsref.py", "loader", "licenses", "__pycache__",
              "*.pyc")
"""Files and folders of the greyfmu package that build FMUs and are not embedded in them."""
ARCHIVE_TIME = (1980, 1, 1, 0, 0, 0)
"""The time stamp of every archive entry, so that rebuilding changes no byte but what changed."""

BASE_UNITS: dict[str, dict[str, str]] = {
    "1": {},
    "s": {"s": "1"},
    "%": {"factor": "0.01"},
    "%/s": {"s": "-1", "factor": "0.01"},
    "MW": {"kg": "1", "m": "2", "s": "-3", "factor": "1e6"},
    "mm": {"m": "1", "factor": "0.001"},
    "kg/m3": {"kg": "1", "m": "-3"},
    "kgf/cm2": {"kg": "1", "m": "-1", "s": "-2", "factor": "98066.5"},
    "rad/s": {"rad": "1", "s": "-1"},
    "MPa": {"kg": "1", "m": "-1", "s": "-2", "factor": "1e6"},
    "kg/s": {"kg": "1", "s": "-1"},
}
"""SI base-unit exponents of the units the slaves use, for ``UnitDefinitions``."""


class UnknownFmuError(ValueError):
    """A requested FMU name has no ``fmus/<Name>.py``."""


def fmu_names() -> list[str]:
    """Names of the FMUs that can be built: the ``fmus/*.py`` files not starting with ``_``."""
    if not FMU_SOURCES.is_dir():
        raise BuildError(
            f"no fmus/ folder next to the greyfmu package (looked for {FMU_SOURCES}); "
            "greyfmu build needs a source checkout installed with `pip install -e .`"
        )
    return sorted(path.stem for path in FMU_SOURCES.glob("*.py") if not path.name.startswith("_"))


def fmi3_fmu_names() -> list[str]:
    """Names of the FMI 3.0 FMUs that can be built: ``fmus/fmi3/*.py`` not starting with ``_``.
    They are built when named (``greyfmu build PID3``, or an SSD naming ``resources/PID3.fmu``),
    not by a plain ``greyfmu build``, which builds the FMI 2.0 set."""
    return sorted(path.stem for path in FMI3_SOURCES.glob("*.py") if not path.name.startswith("_"))


def build_fmus(
    names: Iterable[str] | None = None,
    out_dir: str | Path | None = None,
    force: bool = False,
    echo: Callable[[str], None] | None = None,
) -> list[Path]:
    """Build the named FMUs (all FMI 2.0 ones when ``names`` is None) into ``out_dir`` (default build/fmus).

    An FMU newer than all its sources (its script, ``fmus/_slave.py``, every file of the
    greyfmu package, the loader's C source included) is kept unless ``force`` or it was built
    without a loader that a compiler now on PATH can build (mingw-w64 installed since).  ``echo`` receives one line per FMU.  Returns the
    FMU paths in the order of ``names``.
    """
    available = fmu_names() + fmi3_fmu_names()
    requested = fmu_names() if names is None else list(names)
    unknown = [name for name in requested if name not in available]
    if unknown:
        raise UnknownFmuError(f"unknown FMU {', '.join(unknown)}; valid names: {', '.join(available)}")
    out_dir = DEFAULT_OUT_DIR if out_dir is None else Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    newest_common_source = _newest_mtime(PACKAGE_DIR)
    paths = []
    for name in requested:
        script = FMU_SOURCES / f"{name}.py"
        if not script.is_file():
            script = FMI3_SOURCES / f"{name}.py"
        base = SLAVE_BASE3 if script.parent == FMI3_SOURCES else SLAVE_BASE
        fmu = out_dir / f"{name}.fmu"
        newest_source = max(newest_common_source, base.stat().st_mtime, script.stat().st_mtime)
        if not force and fmu.is_file() and fmu.stat().st_mtime > newest_source \
                and not (base == SLAVE_BASE and _misses_a_loader(fmu)):
            status = "up to date"
        else:
            _build_one(script, fmu)
            status = "built"
        if echo is not None:
            echo(f"{name}: {status} ({fmu})")
        paths.append(fmu)
    return paths


def _newest_mtime(folder: Path) -> float:
    """The newest modification time of the files under ``folder``, ``__pycache__`` folders
    left out (``os.walk``: a quarter of the time of ``Path.rglob``, paid by every run that
    asks the FMU provider, issue 28)."""
    newest = 0.0
    for parent, dirs, files in os.walk(folder):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for name in files:
            newest = max(newest, os.stat(os.path.join(parent, name)).st_mtime)
    return newest


def _misses_a_loader(fmu: Path) -> bool:
    """True when ``fmu`` ships pythonfmu's own library for a platform whose loader compiler is on
    PATH now: an FMI 2.0 drop-in FMU built with the loader keeps pythonfmu's library beside it as
    ``pythonfmu-export.*``, so a platform folder without that file was built without the loader."""
    with zipfile.ZipFile(fmu) as archive:
        names = set(archive.namelist())
    return any(compiler(platform) is not None
               and any(name.startswith(f"binaries/{platform.folder}/") and name.endswith(platform.suffix) for name in names)
               and f"binaries/{platform.folder}/{platform.pythonfmu_library}" not in names
               for platform in PLATFORMS)


def provide_fmu(file_name: str) -> Path | None:
    """FMU provider for the co-simulation master (entry point ``cosim.fmu_providers``).

    Given a file name such as ``"PID.fmu"``, return the FMU in build/fmus, building it
    first if it is missing or stale; None if it is not one of ours or there is no
    ``fmus/`` folder to build from (a non-editable install).
    """
    name = Path(file_name)
    if name.suffix != ".fmu" or not FMU_SOURCES.is_dir() or name.stem not in fmu_names() + fmi3_fmu_names():
        return None

    def report(line: str) -> None:
        if ": built" in line:
            print(f"greyfmu: {line}", file=sys.stderr)

    return build_fmus([name.stem], echo=report)[0]


def _build_one(script: Path, fmu: Path) -> None:
    if script.parent == FMI3_SOURCES:
        _build_one_fmi3(script, fmu)
        return
    _forget_embedded_copies(script)
    with tempfile.TemporaryDirectory(prefix="greyfmu-build-") as temp:
        staged_package = Path(temp) / "package" / PACKAGE_DIR.name
        shutil.copytree(PACKAGE_DIR, staged_package, ignore=shutil.ignore_patterns(*BUILD_ONLY))
        built = FmuBuilder.build_FMU(
            script,
            dest=Path(temp) / "fmu",
            project_files=[staged_package, SLAVE_BASE],
            needsExecutionTool="false",
            canGetAndSetFMUstate="true",  # fmus/_slave.py: the whole instance, deep-copied
            canSerializeFMUstate="true",  # pickled, read back by _slave.StateUnpickler
        )
        script_class = slave_class(script)
        partial = fmu.with_name(f".{fmu.name}.{os.getpid()}.partial")  # same folder: the replace is atomic
        _rewrite_model_description(Path(built), partial, script_class.output_dependencies, script_class.requirements)
        with_reference(partial, _write_archive)  # extra/org.fmi-standard.fmi-ls-ref (greyfmu.lsref)
        os.replace(partial, fmu)


def slave_class(script: Path) -> type:
    """The slave class of ``fmus/<Name>.py`` as the source tree defines it (imported with fmus/
    on sys.path, after `_forget_embedded_copies`)."""
    _forget_embedded_copies(script)
    sys.path.insert(0, str(FMU_SOURCES))
    try:
        return get_model_class(script)
    finally:
        sys.path.remove(str(FMU_SOURCES))


def _forget_embedded_copies(script: Path) -> None:
    """Drop from sys.modules the ``_slave`` and slave module an FMU of ours left in this process:
    pythonfmu imports them from the FMU's resources/, and their base class is the FMU's
    greyfmu_pythonfmu Fmi2Slave, which pythonfmu's builder does not recognise.  Running FMU
    instances keep their classes; the next import reads fmus/."""
    for name in (SLAVE_BASE.stem, script.stem):
        module = sys.modules.get(name)
        if module is not None and Path(getattr(module, "__file__", "") or "").parent != FMU_SOURCES:
            del sys.modules[name]


def _rewrite_model_description(source: Path, target: Path, output_dependencies: dict[str, list[str]],
                               requirements: tuple[str, ...]) -> None:
    with zipfile.ZipFile(source) as archive:
        entries = {info.filename: archive.read(info) for info in archive.infolist()}
    root = ElementTree.fromstring(entries["modelDescription.xml"])
    model = root.get("modelName")
    _declare_output_dependencies(root, model, output_dependencies)
    _declare_units(root, model)
    _write_archive(target, drop_in(entries, root, requirements))


def _write_archive(target: Path, entries: dict[str, bytes]) -> None:
    """The FMU archive: entries in name order, each with `ARCHIVE_TIME` (executables keep their mode)."""
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, ARCHIVE_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if name.startswith("binaries/") else 0o644) << 16
            archive.writestr(info, entries[name])


def _declare_output_dependencies(root: ElementTree.Element, model: str, output_dependencies: dict[str, list[str]]) -> None:
    variables = root.findall("ModelVariables/ScalarVariable")
    index_of = {variable.get("name"): position for position, variable in enumerate(variables, start=1)}
    inputs = {variable.get("name") for variable in variables if variable.get("causality") == "input"}
    outputs = [variable for variable in variables if variable.get("causality") == "output"]
    output_names = {variable.get("name") for variable in outputs}
    if set(output_dependencies) != output_names:
        raise BuildError(
            f"{model}: output_dependencies names {sorted(output_dependencies)}, "
            f"but the outputs are {sorted(output_names)}"
        )
    for variable in outputs:
        name = variable.get("name")
        if variable.get("initial") != "exact" or variable[0].get("start") is None:
            raise BuildError(f'{model}: output {name} needs initial="exact" and a start value')
        not_inputs = [dependency for dependency in output_dependencies[name] if dependency not in inputs]
        if not_inputs:
            raise BuildError(f"{model}: output {name} depends on {not_inputs}, which are not inputs ({sorted(inputs)})")
    for unknown in root.findall("ModelStructure/Outputs/Unknown"):
        name = variables[int(unknown.get("index")) - 1].get("name")
        unknown.set("dependencies", " ".join(str(index_of[dependency]) for dependency in output_dependencies[name]))


def _build_one_fmi3(script: Path, fmu: Path) -> None:
    """Build an FMI 3.0 FMU with pythonfmu3 0.3.4 and repair its model description:

    - ``canHandleVariableCommunicationStepSize`` is written "false" whatever the slave can do
      (pythonfmu3 copies the last common option's value into every Co-Simulation option); our
      slaves handle any step, so it is set through the builder option;
    - ``ModelStructure/Output`` gets ``dependencies`` (value references, FMI 3.0 §2.4.8) from
      the slave class's ``output_dependencies``: absent, it means "depends on every input";
    - ``UnitDefinitions`` declares the units the Float64 variables use (FMI 3.0 requires it);
    - each ``EnumerationType`` pythonfmu3 writes for a mode parameter gets its description and
      its items' from the IntEnum (the members' docstrings).

    Outputs keep pythonfmu3's ``initial="calculated"`` (the FMI 3.0 default for outputs), so they
    carry no start value and are listed as InitialUnknowns, as FMI 3.0 §2.4.8 requires.
    """
    from pythonfmu3.builder import FmuBuilder as Fmu3Builder

    with tempfile.TemporaryDirectory(prefix="greyfmu-build-") as temp:
        staged_package = Path(temp) / "package" / PACKAGE_DIR.name
        shutil.copytree(PACKAGE_DIR, staged_package, ignore=shutil.ignore_patterns(*BUILD_ONLY))
        built = Fmu3Builder.build_FMU(script, dest=Path(temp) / "fmu", project_files=[staged_package, SLAVE_BASE3],
                                      needsExecutionTool="false", canHandleVariableCommunicationStepSize="true")
        with zipfile.ZipFile(built) as archive:
            entries = {info.filename: archive.read(info) for info in archive.infolist()}
        if not any(name.startswith("binaries/") for name in entries):
            # pythonfmu3 copies its library from beside its own module: imported from a pythonfmu3
            # FMU's resources/pythonfmu3/ (an FMU run earlier in this process) it has none
            raise BuildError(f"{script.stem}: pythonfmu3's builder ({Fmu3Builder.__module__} from "
                             f"{sys.modules[Fmu3Builder.__module__].__file__}) put no binaries in the FMU; an FMI 3.0 "
                             "FMU run in this process shadows the installed pythonfmu3: build in a fresh process")
        root = ElementTree.fromstring(entries["modelDescription.xml"])
        model = root.get("modelName")
        slave_class = _slave_class3(script)
        _declare_output_dependencies3(root, model, slave_class.output_dependencies)
        _declare_units(root, model, tag="Float64")
        _describe_enumerations3(root, model, slave_class(instance_name="greyfmu-build", resources=str(FMI3_SOURCES)).choices)
        ElementTree.indent(root)
        entries["modelDescription.xml"] = ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True)
        partial = fmu.with_name(f".{fmu.name}.{os.getpid()}.partial")
        with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for name, data in entries.items():
                archive.writestr(name, data)
        with_reference(partial, _write_archive)  # extra/org.fmi-standard.fmi-ls-ref (greyfmu.lsref)
        os.replace(partial, fmu)


def _slave_class3(script: Path) -> type:
    """The slave class of an FMI 3.0 script (named as the file), imported with fmus/fmi3 on sys.path."""
    import importlib.util

    sys.path.insert(0, str(script.parent))
    try:
        spec = importlib.util.spec_from_file_location(f"_greyfmu_fmi3_{script.stem}", script)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(script.parent))
    return getattr(module, script.stem)


def _declare_output_dependencies3(root: ElementTree.Element, model: str,
                                  output_dependencies: dict[str, list[str]]) -> None:
    variables = [node for node in root.find("ModelVariables") if node.get("name")]
    vr_of = {node.get("name"): node.get("valueReference") for node in variables}
    inputs = {node.get("name") for node in variables if node.get("causality") == "input"}
    outputs = {node.get("valueReference"): node.get("name") for node in variables if node.get("causality") == "output"}
    if set(output_dependencies) != set(outputs.values()):
        raise BuildError(f"{model}: output_dependencies names {sorted(output_dependencies)}, "
                         f"but the outputs are {sorted(outputs.values())}")
    for unknown in root.findall("ModelStructure/Output"):
        dependencies = output_dependencies[outputs[unknown.get("valueReference")]]
        not_inputs = [dependency for dependency in dependencies if dependency not in inputs]
        if not_inputs:
            raise BuildError(f"{model}: an output depends on {not_inputs}, which are not inputs ({sorted(inputs)})")
        unknown.set("dependencies", " ".join(vr_of[dependency] for dependency in dependencies))


def _declare_units(root: ElementTree.Element, model: str, tag: str = "Real") -> None:
    used = sorted({unit for unit in (node.get("unit") for node in root.iter(tag)) if unit is not None})
    if not used:
        return
    unknown = [unit for unit in used if unit not in BASE_UNITS]
    if unknown:
        raise BuildError(f"{model}: units {unknown} are not in greyfmu.build.BASE_UNITS; add their SI base units there")
    definitions = ElementTree.Element("UnitDefinitions")
    for unit in used:
        ElementTree.SubElement(ElementTree.SubElement(definitions, "Unit", name=unit), "BaseUnit", BASE_UNITS[unit])
    position = list(root).index(root.find("CoSimulation")) + 1
    root.insert(position, definitions)


def _describe_enumerations3(root: ElementTree.Element, model: str, choices: dict[str, type[IntEnum]]) -> None:
    """Describe each ``TypeDefinitions/EnumerationType`` (FMI 3.0 §2.4.4) and its items from
    the IntEnum of the same name (``choices``: parameter name -> IntEnum)."""
    types = {enumeration.__name__: enumeration for enumeration in choices.values()}
    for node in root.iter("EnumerationType"):
        description, members = _enumeration_items(model, types[node.get("name")])
        node.set("description", description)
        descriptions = {member.name: item_description for member, item_description in members.items()}
        for item in node.iter("Item"):
            item.set("description", descriptions[item.get("name")])


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
