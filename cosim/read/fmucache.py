"""Unpacked FMUs shared by runs and processes, by content hash (issue 28).

Extracting an FMU is most of a run's fixed cost for a pythonfmu FMU (hundreds of files, tens
of milliseconds each FMU), so each FMU file content is extracted once per machine and user:

- where: ``$COSIM_FMU_CACHE`` if set (``off`` turns the cache off: each process extracts into
  a temporary folder of its own, `cosim.run.instances.unzip`), else ``$XDG_CACHE_HOME/cosim/fmus``,
  else ``~/.cache/cosim/fmus``;
- an entry is ``<sha256 of the FMU file>/`` holding ``fmu/`` (the extracted archive) and
  ``complete.json`` (written last: the bytes extracted).  A modified FMU file has a new hash,
  so a new entry; an entry without its marker (a crash, a hand edit) is removed and rebuilt;
- an entry is made atomically: extracted into ``.tmp-<pid>-*`` beside it, with the checks of
  `cosim.safeio.extract_archive` (names, links, methods, ratio, size), marked, then renamed
  into place.  Of two processes extracting the same FMU at once, one rename wins and the
  other's copy is removed; neither ever sees half an entry;
- entries are used read-only (their files lose their write permission); the archive checks
  ran once for that content, and the size limit in force is compared with the marker's
  ``unpacked_bytes`` each time an entry is used;
- the checks of an FMU file that do not depend on the run (`cosim.read.loadable`'s archive, entity
  and library checks, the FMI schema validation of `cosim.read.description`) are made once per
  content: a check passed leaves an empty file ``verdicts/<sha256>-<check>`` (failures are
  never kept, so their message is always fresh; `CHECKS_VERSION` is part of the name);
- no size limit: ``rm -rf ~/.cache/cosim/fmus`` (or ``$COSIM_FMU_CACHE``) empties it at any
  time no run is starting.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import stat
import tempfile
from pathlib import Path

from ..errors import SetupError
from ..safeio import _alive, _size_text, check_archive, extract_archive, max_unpacked_bytes, write_atomic

#: environment variable naming the cache folder, or "off"
CACHE_ENV = "COSIM_FMU_CACHE"
#: the file written last into an entry: the entry is complete
MARKER = "complete.json"
_TMP = ".tmp-"
_TRASH = ".trash-"
#: part of every verdict's name: raised when a cached check changes, so older verdicts are not trusted
CHECKS_VERSION = 1
#: the digests of the files seen by this process, by (path, size, mtime)
_digests: dict[tuple, str] = {}


def cache_root() -> Path | None:
    """The cache folder in force, or None when ``COSIM_FMU_CACHE=off``."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen:
        return None if chosen.strip().lower() == "off" else Path(chosen)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "cosim" / "fmus"


def digest(path: Path) -> str:
    """The SHA-256 of a file's content, in hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1024 * 1024):
            h.update(chunk)
    return h.hexdigest()


def file_digest(path: Path) -> str:
    """`digest` of a file, computed once per process and file version (path, size, mtime)."""
    path = path.resolve()
    stat_ = path.stat()
    key = (path, stat_.st_size, stat_.st_mtime_ns)
    if key not in _digests:
        _digests[key] = digest(path)
    return _digests[key]


def _verdict(path: Path, check: str) -> Path | None:
    """Where the pass of ``check`` on ``path`` is kept, or None (no cache, not a file)."""
    root = cache_root()
    if root is None or not path.is_file():
        return None
    tag = hashlib.sha256(f"{CHECKS_VERSION}\0{check}".encode()).hexdigest()[:16]
    return root / "verdicts" / f"{file_digest(path)}-{tag}"


def passed(path: Path, check: str) -> bool:
    """Whether ``check`` (a name with what it depends on, e.g. the size limit) passed on this content before."""
    try:
        verdict = _verdict(path, check)
        return verdict is not None and verdict.is_file()
    except OSError:
        return False


def record_pass(path: Path, check: str) -> None:
    """Keep that ``check`` passed on ``path``'s content (nothing when the cache cannot be written)."""
    try:
        verdict = _verdict(path, check)
        if verdict is not None:
            verdict.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(verdict, b"")
    except OSError:
        pass


def unpacked(path: Path, root: Path) -> Path:
    """The folder holding the extracted FMU ``path`` in the cache ``root``, extracted now if
    no complete entry of its content exists; `SetupError` for an archive the checks refuse.
    Raises `OSError` when the cache cannot be written (the caller extracts elsewhere)."""
    entry = root / file_digest(path)
    for _ in range(3):   # a corrupt entry removed, or a concurrent rebuild, then tried again
        done = _complete(entry, path)
        if done is not None:
            return done
        if entry.exists():
            _remove(entry, root)
            continue
        _build(path, entry, root)
    raise OSError(f"the FMU cache entry {entry} could not be made")


def _complete(entry: Path, path: Path) -> Path | None:
    """``entry/fmu`` if the entry is complete (and within the size limit in force), else None."""
    try:
        verdict = json.loads((entry / MARKER).read_text())
        size = int(verdict["unpacked_bytes"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    limit, source = max_unpacked_bytes()
    if size > limit:
        check_archive(path)   # refuses it naming the limit and the member
        raise SetupError(f"the archive expands to {_size_text(size)}, more than the limit of {_size_text(limit)} "
                         f"({limit} bytes, {source}).", file=str(path))
    return entry / "fmu"


def _build(path: Path, entry: Path, root: Path) -> None:
    """Extract ``path`` into a temporary folder beside ``entry``, mark it, rename it into place."""
    root.mkdir(parents=True, exist_ok=True)
    _sweep(root)
    tmp = Path(tempfile.mkdtemp(prefix=f"{_TMP}{os.getpid()}-", dir=root))
    try:
        extract_archive(path, tmp / "fmu", required="modelDescription.xml")
        size = sum(f.stat().st_size for f in (tmp / "fmu").rglob("*") if f.is_file())
        _read_only(tmp / "fmu")
        (tmp / MARKER).write_text(json.dumps({"unpacked_bytes": size, "source": str(path)}))
        try:
            os.rename(tmp, entry)
        except OSError:   # another process made the entry first: use that one
            pass
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _read_only(folder: Path) -> None:
    """Take the write permission off every file (folders keep theirs, so the cache can be emptied)."""
    for f in folder.rglob("*"):
        if f.is_file():
            f.chmod(stat.S_IMODE(f.stat().st_mode) & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _remove(entry: Path, root: Path) -> None:
    """Take a corrupt entry out of the way in one rename (another process may do the same), then delete it."""
    trash = Path(tempfile.mkdtemp(prefix=f"{_TRASH}{os.getpid()}-", dir=root))
    try:
        os.rename(entry, trash / "entry")
    except OSError:
        pass
    shutil.rmtree(trash, ignore_errors=True)


def _sweep(root: Path) -> None:
    """Remove the temporary folders of processes that no longer exist (a crash mid-extraction)."""
    for prefix in (_TMP, _TRASH):
        for folder in root.glob(f"{prefix}*-*"):
            pid = folder.name[len(prefix):].split("-", 1)[0]
            if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
                shutil.rmtree(folder, ignore_errors=True)
