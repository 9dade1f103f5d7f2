"""Find the FMU file behind each component's ``source``.

A component names its FMU as ``resources/<Name>.fmu`` (the SSP archive
convention).  The file is looked for, in order:

1. relative to the SSD (inside an ``.ssp`` archive, or the scenario's own
   ``resources/`` folder) — a user's third-party FMU dropped into a scenario;
2. by FMU providers: packages that build FMUs register a function under the
   entry-point group ``cosim.fmu_providers``; it is called with the FMU name and
   returns a path (building the FMU first if it is missing or stale) or None.
   greyfmu registers one, so ``cosim run ssp/pid_fopdt`` builds what it needs.
   The master never imports such a package by name;
3. in the folders given with ``--fmu-dir``.

An FMU found nowhere is an error whose "did you mean" offers the close names among the files
of those folders and the names the providers make (entry-point group ``cosim.fmu_names``).

The providers are loaded only when a component's FMU is not next to the SSD (loading them
imports their packages: tens of milliseconds of a run's fixed cost, issue 28).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from importlib.metadata import entry_points
from pathlib import Path, PurePosixPath

from ..errors import SetupError, did_you_mean
from ..safeio import is_file
from .ssp import resolve_uri
from ..model.structure import Component, SystemStructure

Provider = Callable[[str], "Path | None"]


def providers() -> tuple[list[Provider], list[str]]:
    """The FMU providers registered under ``cosim.fmu_providers`` that load, and for each one that
    does not (greyfmu's without pythonfmu installed) what it is and why, for the message of an FMU
    not found: a provider that cannot be imported does not stop a run whose FMUs are elsewhere."""
    loaded: list[Provider] = []
    broken: list[str] = []
    for ep in entry_points(group="cosim.fmu_providers"):
        try:
            loaded.append(ep.load())
        except ImportError as e:
            broken.append(f"{ep.value} (not loaded: {e})")
    return loaded, broken


def locate_fmus(structure: SystemStructure, fmu_dirs: Sequence[Path] = (),
                use_providers: bool = True) -> dict[str, Path]:
    """The FMU file of every component, by component path, or raise naming what was looked at;
    each ``source`` located once (a system of 1000 copies of one FMU looks for it once)."""
    asked = _Providers(use_providers)
    found: dict[str, Path] = {}
    located = {}
    for name, comp in structure.components.items():
        if not comp.source or comp.source not in found:
            found[comp.source] = _locate(comp, structure, fmu_dirs, asked)
        located[name] = found[comp.source]
    return located


class _Providers:
    """The FMU providers, loaded when the first FMU is not found next to the SSD; each file name
    asked once (a system of many copies of one FMU checks that it is up to date once)."""

    def __init__(self, use: bool):
        self.use = use
        self._loaded: list[Provider] | None = None
        self.broken: list[str] = []
        self._answers: dict[str, Path | None] = {}

    @property
    def loaded(self) -> list[Provider]:
        if self._loaded is None:
            self._loaded, self.broken = providers() if self.use else ([], [])
        return self._loaded

    def provide(self, name: str) -> Path | None:
        if name not in self._answers:
            found = (provide(name) for provide in self.loaded)
            self._answers[name] = next((Path(path) for path in found if path is not None), None)
        return self._answers[name]


def _locate(comp: Component, structure: SystemStructure, fmu_dirs: Sequence[Path], asked: _Providers) -> Path:
    where = f"ssd:Component '{comp.name}' (line {comp.line})"
    if not comp.source:
        raise SetupError("the component has no source attribute naming its FMU.",
                         file=structure.display, element=where)
    looked: list[str] = []
    archive_root = structure.base_dir.resolve() if structure.archive is not None else None
    try:
        direct = resolve_uri(comp.source, structure.base_dir, archive_root)
    except SetupError as e:
        raise SetupError(e.detail, file=str(structure.archive or structure.ssd_file), element=where) from None
    if is_file(direct):
        return direct
    looked.append(str(direct))
    name = PurePosixPath(comp.source).name
    provided = asked.provide(name)
    if provided is not None:
        return provided
    if asked.loaded or asked.broken:
        looked.append("the FMU providers (" + ", ".join([p.__module__ for p in asked.loaded] + asked.broken) + ")")
    for d in fmu_dirs:
        candidate = Path(d) / name
        if is_file(candidate):
            return candidate
        looked.append(str(candidate))
    close = did_you_mean(name, _known_names([direct.parent, *map(Path, fmu_dirs)], asked.use))
    raise SetupError(f"the FMU file '{comp.source}' was not found; looked at " + "; ".join(looked) + ".",
                     file=str(structure.archive or structure.ssd_file), element=where,
                     hint=(close + " " if close else "") + "Put the FMU in the scenario's resources/ folder or pass "
                     "--fmu-dir FOLDER.")


def _known_names(folders: Sequence[Path], use_providers: bool) -> list[str]:
    """The FMU file names a "did you mean" offers for one not found: the ``.fmu`` files of the
    folders looked in, and the names the FMU providers make (entry points ``cosim.fmu_names``:
    functions returning file names; one that fails to load or answer is left out)."""
    names = {path.name for folder in folders if folder.is_dir() for path in folder.glob("*.fmu")}
    if use_providers:
        for ep in entry_points(group="cosim.fmu_names"):
            try:
                names.update(ep.load()())
            except Exception:  # a broken provider must not hide the error being reported
                continue
    return sorted(names)
