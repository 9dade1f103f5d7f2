"""Build the FMUs of ``fmus/`` with pythonfmu and repair what pythonfmu 0.7.0 writes wrong.

Each ``fmus/<Name>.py`` becomes ``<out_dir>/<Name>.fmu`` (FMI 2.0 Co-Simulation) with the
``greyfmu`` package and ``fmus/_slave.py`` embedded as resources, and on demand its FMI 3.0
sibling ``<out_dir>/<Name>3.fmu`` from the same slave (`greyfmu.fmi3`, with
``fmus/fmi3/_slave3.py``).  The archive's modelDescription.xml is then post-processed:

- every output must have ``initial="exact"`` and a start value (the build fails otherwise);
- ``ModelStructure/Outputs/Unknown`` gets ``dependencies`` from the slave class's
  ``output_dependencies`` (pythonfmu omits it, which means "depends on every input");
- ``UnitDefinitions`` declares every unit the variables use;
- the ``org.greyfmu`` annotation (`greyfmu.wiring`) says the sample time and what to wire (the FMI
  2.0 description's VendorAnnotations, the FMI 3.0 one's Annotations);
- then `greyfmu.dropin` makes it a drop-in FMU: greyfmu's loader as the linux64 binary, a
  stable GUID, version/licence/copyright, ``documentation/`` with index.html and the licences;
- last, `greyfmu.lsref` adds the FMI-LS-REF reference experiment (``extra/``), run on the FMU built.

The embedded greyfmu package leaves out what only builds FMUs (`BUILD_ONLY`).

``dependenciesKind`` is not written: absent, it means "dependent", which is all the
slaves can promise in general.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterable
from pathlib import Path
from xml.etree import ElementTree

from pythonfmu.builder import FmuBuilder, get_model_class

from greyfmu.dropin import BuildError, drop_in
from greyfmu.fmi3 import SUFFIX, _enumeration_items, drop_in3, fmi3_name, model_description3  # noqa: F401 (tests)
from greyfmu.loader import PLATFORMS, compiler
from greyfmu.lsref import with_reference
from greyfmu.names import canonical_name, unknown_message
from greyfmu.wiring import annotate

PACKAGE_DIR = Path(__file__).resolve().parent
REPOSITORY_ROOT = PACKAGE_DIR.parent
FMU_SOURCES = REPOSITORY_ROOT / "fmus"
SLAVE_BASE = FMU_SOURCES / "_slave.py"
FMI3_SOURCES = FMU_SOURCES / "fmi3"
SLAVE_BASE3 = FMI3_SOURCES / "_slave3.py"
IN_PROCESS = FMU_SOURCES / "_inprocess.py"
SLAVE_FILES = (SLAVE_BASE, IN_PROCESS, FMU_SOURCES / "_state.py")
"""The modules every FMI 2.0 FMU embeds next to its slave module (and the greyfmu package)."""
SLAVE_FILES3 = (*SLAVE_FILES, SLAVE_BASE3)
"""The modules every FMI 3.0 FMU embeds next to its slave module (and the greyfmu package)."""
DEFAULT_OUT_DIR = REPOSITORY_ROOT / "build" / "fmus"
BUILD_ONLY = ("build.py", "cli.py", "dropin.py", "documentation.py", "fmi3.py", "privatise.py", "catalogue.py",
              "names.py", "wiring.py", "lsref.py", "loader", "licenses", "__pycache__", "*.pyc")
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
    """Names of the FMI 3.0 FMUs that can be built: ``<Name>3`` for each of `fmu_names`, built
    from the same ``fmus/<Name>.py`` (greyfmu.fmi3).  They are built when named (``greyfmu build
    PID3``, ``greyfmu build --fmi 3``, or an SSD naming ``resources/PID3.fmu``), not by a plain
    ``greyfmu build``, which builds the FMI 2.0 set."""
    names = fmu_names()
    clashes = [name for name in names if fmi3_name(name) in names]
    if clashes:
        raise BuildError(f"fmus/{fmi3_name(clashes[0])}.py is named like the FMI 3.0 build of fmus/{clashes[0]}.py")
    return [fmi3_name(name) for name in names]


def fmi2_name(name: str) -> str | None:
    """The FMI 2.0 sibling's name of the FMI 3.0 FMU ``name`` (PID3 -> PID); None if it is not one."""
    return name[:-len(SUFFIX)] if name.endswith(SUFFIX) and name in fmi3_fmu_names() else None


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
    requested = fmu_names() if names is None else [canonical_name(name, available) for name in names]
    unknown = [name for name in requested if name not in available]
    if unknown:
        raise UnknownFmuError(unknown_message(unknown, available))
    out_dir = DEFAULT_OUT_DIR if out_dir is None else Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    newest_common_source = _newest_mtime(PACKAGE_DIR)
    paths = []
    for name in requested:
        sibling = fmi2_name(name) if name not in fmu_names() else None
        script = FMU_SOURCES / f"{sibling or name}.py"
        slave_files = SLAVE_FILES3 if sibling else SLAVE_FILES
        fmu = out_dir / f"{name}.fmu"
        newest_source = max(newest_common_source, script.stat().st_mtime, *(f.stat().st_mtime for f in slave_files))
        if not force and fmu.is_file() and fmu.stat().st_mtime > newest_source and not _misses_a_loader(fmu):
            status = "up to date"
        else:
            _build_one(script, fmu, fmi3=sibling is not None)
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
    """True when ``fmu`` ships pythonfmu's (pythonfmu3's) own library for a platform whose loader
    compiler is on PATH now: a drop-in FMU built with the loader keeps that library beside it as
    ``pythonfmu-export.*`` (``pythonfmu3-export.*``), so a platform folder without that file was
    built without the loader."""
    with zipfile.ZipFile(fmu) as archive:
        names = set(archive.namelist())
    return any(compiler(platform) is not None
               and any(name.startswith(f"binaries/{folder}/") and name.endswith(platform.suffix) for name in names)
               and f"binaries/{folder}/{library}" not in names
               for platform in PLATFORMS
               for folder, library in ((platform.folder, platform.pythonfmu_library),
                                       (platform.folder3, platform.pythonfmu3_library)))


def provide_fmu(file_name: str) -> Path | None:
    """FMU provider for the co-simulation master (entry point ``cosim.fmu_providers``).

    Given a file name such as ``"PID.fmu"``, return the FMU in build/fmus, building it
    first if it is missing or stale; None if it is not one of ours or there is no
    ``fmus/`` folder to build from (a non-editable install).
    """
    name = Path(file_name)
    if name.suffix != ".fmu" or not FMU_SOURCES.is_dir():
        return None
    stem = canonical_name(name.stem, fmu_names() + fmi3_fmu_names())  # greyfmu.names: GreyPredictivePI too
    if stem not in fmu_names() + fmi3_fmu_names():
        return None

    def report(line: str) -> None:
        if ": built" in line:
            print(f"greyfmu: {line}", file=sys.stderr)

    return build_fmus([stem], echo=report)[0]


def _build_one(script: Path, fmu: Path, fmi3: bool = False) -> None:
    """Build ``fmu`` from ``script``: FMI 2.0, or with ``fmi3`` its FMI 3.0 sibling (greyfmu.fmi3)."""
    _forget_embedded_copies(script)
    with tempfile.TemporaryDirectory(prefix="greyfmu-build-") as temp:
        staged_package = Path(temp) / "package" / PACKAGE_DIR.name
        shutil.copytree(PACKAGE_DIR, staged_package, ignore=shutil.ignore_patterns(*BUILD_ONLY))
        built = FmuBuilder.build_FMU(
            script,
            dest=Path(temp) / "fmu",
            project_files=[staged_package, *(SLAVE_FILES3 if fmi3 else SLAVE_FILES)],
            needsExecutionTool="false",
            canGetAndSetFMUstate="true",  # fmus/_slave.py: the whole instance, deep-copied
            canSerializeFMUstate="true",  # pickled, read back by _slave.StateUnpickler
        )
        script_class = slave_class(script)
        partial = fmu.with_name(f".{fmu.name}.{os.getpid()}.partial")  # same folder: the replace is atomic
        _rewrite_model_description(Path(built), partial, script_class, fmi3)
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
    """Drop from sys.modules a slave module or slave base of the same name that is not fmus/'s:
    another vendor's pythonfmu FMU run in this process leaves its slave module (``PID``) under its
    public name (ours are private, greyfmu.privatise), and pythonfmu's builder imports the
    script by that name.  Running FMU instances keep their classes; the next import reads fmus/."""
    for name in (*(path.stem for path in SLAVE_FILES), script.stem):
        module = sys.modules.get(name)
        if module is not None and Path(getattr(module, "__file__", "") or "").parent != FMU_SOURCES:
            del sys.modules[name]


def _rewrite_model_description(source: Path, target: Path, script_class: type, fmi3: bool) -> None:
    with zipfile.ZipFile(source) as archive:
        entries = {info.filename: archive.read(info) for info in archive.infolist()}
    root = ElementTree.fromstring(entries["modelDescription.xml"])
    model = root.get("modelName")
    _declare_output_dependencies(root, model, script_class.output_dependencies)
    _declare_units(root, model)
    if fmi3:
        choices = script_class(instance_name="greyfmu-build").choices
        root3 = model_description3(root, choices)
        annotate(root3, script_class)  # greyfmu.wiring: sample time and what to wire, for cosim's warnings
        _write_archive(target, drop_in3(entries, root3, model, script_class.requirements))
    else:
        annotate(root, script_class)  # greyfmu.wiring
        _write_archive(target, drop_in(entries, root, script_class.requirements))


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


def _declare_units(root: ElementTree.Element, model: str) -> None:
    used = sorted({unit for unit in (node.get("unit") for node in root.iter("Real")) if unit is not None})
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
