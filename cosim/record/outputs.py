"""Output paths checked before anything is instantiated (issue 17).

A run (or ``cosim report``) that would end by failing to write its result, JSON or plot, or by overwriting the
scenario it runs (``cosim run S -o S/SystemStructure.ssd``), is refused up front with exit
status 2: every target must have a known format, must not be a folder nor one of the
scenario's own files (its SSD, .ssp archive, parameter sets, FMUs), and its folder must exist
(or be creatable: missing folders are made, as for the default ``results/``) and be writable.
A default name is made of names from the scenario, each checked to be a file name
(`result_stem`, `cosim.safeio.file_name`).  A sweep's folder belongs to the sweep: a run
writing into it, or a sweep into a folder holding a run's ``sweep.*`` results, is refused
(`check_not_in_sweep`, `check_sweep_folder`).
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from ..errors import SetupError
from ..extras import require_pyarrow
from ..safeio import file_name
from ..model.structure import Plan

#: result formats of `cosim.record.observers.file_sink`
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
    if path.suffix.lower() == ".parquet":
        require_pyarrow(f"a Parquet {what}", element=option)
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


def result_stem(scenario: str, parameter_sets: Iterable[str | Path], *, what: str = "the system name",
                file: str | None = None, element: str | None = None) -> str:
    """``scenario__set1__set2``: the default result name, so runs of different parameter sets
    (cases) never overwrite each other.  ``scenario`` (described by ``what``, ``file`` and
    ``element`` in an error) and each set's stem must be file names (`cosim.safeio.file_name`)."""
    hint = "Give the result's name with --output."
    parts = [file_name(scenario, what=what, file=file, element=element, hint=hint)]
    parts += [file_name(Path(p).stem, what="the parameter set name", file=str(p), element="--param-set", hint=hint)
              for p in parameter_sets]
    return "__".join(parts)


#: what marks a folder as a sweep's: its table, written before its first run (with or without
#: pyarrow), with no `RUN_AS_SWEEP_MARK` beside it
SWEEP_MARK = "sweep.csv"
#: the metadata of a run's result named ``sweep.csv`` or ``sweep.parquet``; a sweep writes no ``sweep.json``
RUN_AS_SWEEP_MARK = "sweep.json"


def _is_sweep_folder(folder: Path) -> bool:
    return (folder / SWEEP_MARK).is_file() and not (folder / RUN_AS_SWEEP_MARK).is_file()


def check_not_in_sweep(path: Path, option: str = "--output") -> None:
    """Refuse a run's result in a sweep's folder or its ``runs/`` folder: it would replace the
    sweep's table or one of its runs, which the next sweep into the folder takes as done."""
    folder = path.resolve().parent
    for candidate in (folder, folder.parent) if folder.name == "runs" else (folder,):
        if _is_sweep_folder(candidate):
            raise SetupError(f"{path} is in the folder of a sweep ({candidate}, which holds {SWEEP_MARK}); a "
                             "run's results there would replace the sweep's table or runs. Choose another "
                             "folder.", element=option)


def check_sweep_folder(path: Path, option: str = "--output") -> Path:
    """``path`` if a sweep can write its table and runs there: a folder, or none yet (its nearest
    existing parent a writable folder), not holding a run's results named ``sweep.*``."""
    if path.exists() and not path.is_dir():
        raise SetupError(f"{path} is a file; a sweep's output is a folder (for sweep.csv, sweep.parquet and "
                         "runs/). Give a folder name.", element=option)
    existing = next(p for p in (path.resolve(), *path.resolve().parents) if p.exists())
    if not existing.is_dir():
        raise SetupError(f"{path}: {existing} is a file, not a folder.", element=option)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise SetupError(f"{path}: the folder {existing} is not writable.", element=option)
    if (path / RUN_AS_SWEEP_MARK).is_file():
        raise SetupError(f"{path} holds a run's results named sweep.* ({path / RUN_AS_SWEEP_MARK} is its "
                         "metadata), which the sweep's table would replace. Choose another folder.",
                         element=option)
    return path


def plot_suffixes() -> tuple[str, ...]:
    """The file formats matplotlib's Agg canvas writes (``.png``, ``.pdf``, ``.svg``, ...)."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    return tuple(f".{s}" for s in Figure().canvas.get_supported_filetypes())
