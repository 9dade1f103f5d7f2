"""Output paths checked before anything is instantiated (issue 17).

A run (or ``cosim report``) that would end by failing to write its result, JSON or plot, or by overwriting the
scenario it runs (``cosim run S -o S/SystemStructure.ssd``), is refused up front with exit
status 2: every target must have a known format, must not be a folder nor one of the
scenario's own files (its SSD, .ssp archive, parameter sets, FMUs), and its folder must exist
(or be creatable: missing folders are made, as for the default ``results/``) and be writable.
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from .errors import SetupError
from .structure import Plan

#: result formats of `cosim.observers.file_sink`
RESULT_SUFFIXES = (".csv", ".parquet")


def scenario_files(plan: Plan) -> set[Path]:
    """The files a scenario is made of, resolved: what must never be written over."""
    files = plan.files
    own = {files.ssd_file, *(d.path for d in plan.fmus.values())}
    if files.archive is not None:
        own.add(files.archive)
    else:
        own.update(files.base_dir.rglob("*.ssv"))
    return {p.resolve() for p in own}


def check_output(path: Path, own: set[Path], *, what: str, option: str, suffixes: Iterable[str],
                 companions: Iterable[Path] = (), owner: str = "the scenario's") -> Path:
    """``path`` (and the files written beside it, ``companions``) if they can be written; else
    a `SetupError` naming ``option`` and the reason (``own``: the files of ``owner``, never
    written over)."""
    suffixes = tuple(suffixes)
    if path.suffix.lower() not in suffixes:
        raise SetupError(f"{path}: a {what} name must end in {' or '.join(suffixes)}.", element=option)
    for target in (path, *companions):
        if target.is_dir():
            raise SetupError(f"{target} is a folder; give a file name for the {what}.", element=option)
        if target.resolve() in own:
            raise SetupError(f"{target} is one of {owner} own files; writing the {what} there would "
                             "destroy it. Choose another name.", element=option)
    folder = path.resolve().parent
    existing = next(p for p in (folder, *folder.parents) if p.exists())
    if not existing.is_dir():
        raise SetupError(f"{path}: {existing} is a file, not a folder.", element=option)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise SetupError(f"{path}: the folder {existing} is not writable.", element=option)
    return path


def plot_suffixes() -> tuple[str, ...]:
    """The file formats matplotlib's Agg canvas writes (``.png``, ``.pdf``, ``.svg``, ...)."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    return tuple(f".{s}" for s in Figure().canvas.get_supported_filetypes())
