"""Read untrusted SSP input safely: XML without entities, ZIP archives within limits.

An ``.ssp`` archive or ``.ssd`` file may come from anyone (a supplier, a colleague,
a download), so reading it must not be a way to exhaust the machine or to read
other files:

- XML is parsed with entity substitution, DTD loading and network access off and
  libxml2's size limits on (no ``huge_tree``).  A document that declares entities
  (billion laughs, external ``SYSTEM`` entities, parameter entities) or names an
  external DTD is refused: SSP 1.0 documents are defined by XML Schemas, a DTD has
  no role in them.
- ZIP archives are checked before anything is written (member count, declared
  sizes, compression ratio, compression method, names) and the size limit is
  enforced again while extracting, because declared sizes can lie.  Only the
  methods store and deflate are accepted: the ZIP conventions FMI 2.0 §2.3 sets for
  FMUs, which SSP 1.0 archives follow.

Every refusal is a `SetupError` naming the file, the member and the limit.

Files cosim writes are guarded the same way (`file_name`, `lock_output`, `atomic_path`): a
name taken from untrusted text (an SSD's system name, a worker's reply, a regression
reference) is a file name, never a path; one process writes an output at a time; and a
result appears under its name only when it is complete.
"""
from __future__ import annotations

import errno
import os
import re
import shutil
import stat
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path, PurePosixPath
from types import TracebackType

from lxml import etree

from .errors import SetupError

#: Default limit on the bytes an archive may expand to.  An SSP holding a few FMUs
#: with binaries for three platforms is tens to hundreds of MB; 2 GiB leaves room for
#: FMUs carrying large tables while stopping a bomb before it fills a temporary
#: folder (often a RAM-backed tmpfs of a few GiB).
DEFAULT_MAX_UNPACKED_BYTES = 2 * 1024**3
#: Environment variable that sets the limit (bytes, or with a K/M/G/T suffix).
MAX_UNPACKED_ENV = "COSIM_MAX_UNPACKED_BYTES"
#: An SSP archive holds the SSD, parameter sets and one member per FMU and resource.
MAX_MEMBERS = 10_000
#: Deflate of real data (binaries, XML, tables) stays well under 100:1; a bomb is
#: near deflate's ceiling of about 1000:1.  Only members above `RATIO_CHECK_BYTES`
#: are checked, so a small file of zeros is not refused.
MAX_COMPRESSION_RATIO = 200
RATIO_CHECK_BYTES = 1024**2
ALLOWED_METHODS = {zipfile.ZIP_STORED: "store", zipfile.ZIP_DEFLATED: "deflate"}

#: SSD and SSV documents are kilobytes to a few megabytes; beyond this one is not read into memory.
MAX_XML_BYTES = 256 * 1024**2

_CHUNK = 1024**2
_limit_override: ContextVar[int | None] = ContextVar("cosim_max_unpacked_bytes", default=None)


# --------------------------------------------------------------------------- XML

def _parser() -> etree.XMLParser:
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
                           remove_comments=True)


_ENTITY_MARKS = tuple("<!ENTITY".encode(codec) for codec in ("utf-8", "utf-16-le", "utf-16-be"))
#: a document holding one of these has a DOCTYPE (where entities are declared)
DOCTYPE_MARKS = _ENTITY_MARKS + tuple("<!DOCTYPE".encode(codec) for codec in ("utf-8", "utf-16-le", "utf-16-be"))


def parse_xml(path: Path, display: str | None = None) -> etree._ElementTree:
    """Parse an SSP XML document with line numbers; refuse entities and external DTDs.

    A file that is not well formed is reported with its line and column.
    """
    display = display or str(path)
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_XML_BYTES + 1)
    except OSError as e:
        raise SetupError(f"cannot read the file ({e.strerror or e}).", file=display) from None
    if len(data) > MAX_XML_BYTES:
        raise SetupError(f"the document is larger than {_size_text(MAX_XML_BYTES)}, far beyond any SSP "
                         "system structure or parameter set; refusing to parse it.", file=display)
    return parse_xml_bytes(data, display)


def parse_xml_bytes(data: bytes, display: str) -> etree._ElementTree:
    """`parse_xml` of a document already read (an FMU's modelDescription.xml, say)."""
    try:
        tree = etree.fromstring(data, _parser()).getroottree()
    except etree.XMLSyntaxError as e:
        if any(mark in data for mark in _ENTITY_MARKS):
            raise _entities_refused(display, f" (the parser stopped: {e.msg})") from None
        line, col = e.position if e.position else (e.lineno, 0)
        raise SetupError(f"XML is not well formed at line {line}, column {col}: {e.msg}.",
                         file=display) from None
    dtd = tree.docinfo.internalDTD
    if dtd is not None and any(True for _ in dtd.iterentities()):
        names = ", ".join(sorted({e.name for e in dtd.iterentities()})[:5])
        raise _entities_refused(display, f" (declared: {names})")
    if tree.docinfo.system_url or tree.docinfo.public_id:
        raise SetupError(f"the DOCTYPE names an external DTD ({tree.docinfo.system_url or tree.docinfo.public_id}); "
                         "SSP documents are defined by XML Schemas and must not reference a DTD.",
                         file=display, element="DOCTYPE", hint="Delete the <!DOCTYPE ...> line.")
    return tree


def _entities_refused(display: str, detail: str) -> SetupError:
    return SetupError(f"entity declarations are not allowed in SSP documents nor FMU model descriptions{detail}; they are the way "
                      "to the billion-laughs expansion and to reading local files (external entities).",
                      file=display, element="DOCTYPE", hint="Write the values out instead of using entities.")


def is_file(path: Path) -> bool:
    """`Path.is_file`, but False also for a name the system cannot look up (too long, say):
    a file name taken from an SSP document is the user's, and the caller reports it as not found."""
    try:
        return path.is_file()
    except OSError:
        return False


# --------------------------------------------------------------------------- temporary folders

def temporary_folder(prefix: str) -> tempfile.TemporaryDirectory:
    """A ``TemporaryDirectory`` named ``<prefix><pid>-...``, after removing the folders of that
    prefix left by processes that no longer exist (a crash skips the cleanup; the FMU
    extraction folders are 3-4 MB each)."""
    for folder in Path(tempfile.gettempdir()).glob(f"{prefix}*-*"):
        pid = folder.name[len(prefix):].split("-", 1)[0]
        if pid.isdigit() and folder.is_dir() and not _alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)
    return tempfile.TemporaryDirectory(prefix=f"{prefix}{os.getpid()}-")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


# --------------------------------------------------------------------------- ZIP

def parse_size(text: str, source: str) -> int:
    """Bytes from ``"2147483648"``, ``"512M"``, ``"4G"`` or ``"4GiB"`` (binary multiples)."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", text)
    if not m:
        raise SetupError(f"'{text}' is not a size; give bytes or a number with K, M, G or T (binary "
                         "multiples), e.g. 4G.", file=source)
    return int(float(m.group(1)) * 1024 ** "_KMGT".index(m.group(2).upper() or "_"))


@contextmanager
def unpack_limit(max_unpacked_bytes: int | None) -> Iterator[None]:
    """Within the block, archives are read with this limit (None: the environment or default).

    Used by the CLI's ``--max-unpacked``, which cannot reach `cosim.read.ssp.load` through
    every call in between.
    """
    token = _limit_override.set(max_unpacked_bytes)
    try:
        yield
    finally:
        _limit_override.reset(token)


def max_unpacked_bytes(explicit: int | None = None) -> tuple[int, str]:
    """The limit in force and where it comes from: argument, ``--max-unpacked``, environment, default."""
    if explicit is not None:
        return explicit, "the max_unpacked_bytes argument"
    if _limit_override.get() is not None:
        return _limit_override.get(), "--max-unpacked"
    if os.environ.get(MAX_UNPACKED_ENV):
        return parse_size(os.environ[MAX_UNPACKED_ENV], f"environment variable {MAX_UNPACKED_ENV}"), MAX_UNPACKED_ENV
    return DEFAULT_MAX_UNPACKED_BYTES, "the default"


def _size_text(n: int) -> str:
    for unit, scale in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


def _limit_hint() -> str:
    return (f"If the archive is trusted, raise the limit with --max-unpacked SIZE, the environment variable "
            f"{MAX_UNPACKED_ENV} or cosim.read.ssp.load(..., max_unpacked_bytes=N).")


def check_member_name(name: str, archive: Path | str) -> None:
    """Refuse members that are empty, absolute (``/x``, ``C:x``, ``\\\\host``) or escape the archive (``..``)."""
    posix = PurePosixPath(name.replace("\\", "/"))
    if not name.strip("/\\"):
        raise SetupError("an archive member has an empty name.", file=str(archive))
    if posix.is_absolute() or (len(name) > 1 and name[1] == ":"):
        raise SetupError(f"archive member '{name}' has an absolute path; SSP members must be relative.",
                         file=str(archive))
    if ".." in posix.parts:
        raise SetupError(f"archive member '{name}' escapes the archive ('..'); refusing to extract it.",
                         file=str(archive))


def extract_archive(path: Path, dest: Path, limit: int | None = None, required: str | None = None) -> None:
    """Extract a ZIP archive into ``dest`` after checking it.

    ``limit`` is the most bytes the archive may expand to (see `max_unpacked_bytes`);
    ``required`` names a member the archive must hold at its root.  The FMUs among the
    members are archives too, opened and extracted by fmpy later: their directories are
    checked here the same way (`check_archive`), naming them ``archive.ssp!member.fmu``; a
    member that is no zip archive is left to the component that uses it.
    """
    limit, source = max_unpacked_bytes(limit)
    with _open(path, str(path)) as archive:
        infos = archive.infolist()
        _check_members(str(path), infos, limit, source)
        names = [info.filename for info in infos]
        if required is not None and required not in names:
            raise SetupError(f"the archive has no {required} at its root.", file=str(path),
                             hint=f"Members: {', '.join(names[:10]) or 'none'}.")
        total = 0
        for info in infos:
            total = _extract_member(archive, info, path, dest, total, limit, source)
    for info in infos:
        fmu = _target(dest, info.filename)
        # one that is no zip archive at all (empty, truncated) is refused by the component that
        # uses it, naming both (cosim.read.loadable.check_fmu_file); an unused one is never opened
        if info.filename.lower().endswith(".fmu") and not info.is_dir() and zipfile.is_zipfile(fmu):
            check_archive(fmu, limit, display=f"{path}!{info.filename}")


def check_archive(path: Path, limit: int | None = None, display: str | None = None) -> None:
    """Check a ZIP archive's directory (names, sizes, ratio, methods) without extracting it."""
    limit, source = max_unpacked_bytes(limit)
    display = display or str(path)
    with _open(path, display) as archive:
        _check_members(display, archive.infolist(), limit, source)


def read_member(archive: Path, name: str, display: str, element: str) -> bytes:
    """The bytes of the file ``name`` inside the zip ``archive`` (an FMU): ``name`` is checked
    as every archive member is (`check_member_name`: relative, no ``..``), must be a member and
    is read up to `MAX_XML_BYTES` (it is an SSP document); errors name ``display`` and ``element``."""
    try:
        check_member_name(name, archive)
    except SetupError as e:
        raise SetupError(e.detail, file=display, element=element) from None
    with _open(archive, str(archive)) as z:
        member = PurePosixPath(name.replace("\\", "/")).as_posix()   # "./resources/x.ssv" is "resources/x.ssv"
        try:
            info = z.getinfo(member)
        except KeyError:
            raise SetupError(f"'{name}' is not a file in the archive {archive}.", file=display,
                             element=element) from None
        if info.file_size > MAX_XML_BYTES:
            raise SetupError(f"'{name}' in {archive} is larger than {_size_text(MAX_XML_BYTES)}; refusing to read it.",
                             file=display, element=element)
        with z.open(info) as f:
            return f.read(MAX_XML_BYTES + 1)


def _open(path: Path, display: str) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile as e:
        raise SetupError(f"not a zip archive ({e}).", file=display) from None
    except OSError as e:
        raise SetupError(f"cannot read the archive ({e.strerror or e}).", file=display) from None
    except UnicodeDecodeError as e:   # a member name flagged UTF-8 (general purpose bit 11) that is not
        raise SetupError(f"a member name in the archive's central directory is flagged UTF-8 and is not ({e.reason} "
                         f"at byte {e.start}).", file=display) from None


def _target(dest: Path, name: str) -> Path:
    return dest.joinpath(*PurePosixPath(name.replace("\\", "/")).parts)


def _check_members(display: str, infos: list[zipfile.ZipInfo], limit: int, source: str) -> None:
    """Everything that can be refused from the central directory alone, before writing a byte."""
    if len(infos) > MAX_MEMBERS:
        raise SetupError(f"the archive has {len(infos)} members, more than the {MAX_MEMBERS} an SSP archive "
                         "or FMU may hold.", file=display)
    seen: set[str] = set()
    declared = 0
    for info in infos:
        name = info.filename
        check_member_name(name, display)
        key = name.replace("\\", "/").rstrip("/")
        if key in seen:
            raise SetupError(f"archive member '{name}' appears twice; which copy is meant is ambiguous.",
                             file=display)
        seen.add(key)
        if stat.S_ISLNK(info.external_attr >> 16):
            raise SetupError(f"archive member '{name}' is a symbolic link; SSP archives and FMUs hold plain files.",
                             file=display)
        if info.flag_bits & 0x1:
            raise SetupError(f"archive member '{name}' is encrypted; SSP archives and FMUs must not be.", file=display)
        if info.compress_type not in ALLOWED_METHODS:
            raise SetupError(f"archive member '{name}' uses ZIP compression method {info.compress_type}; only "
                             "store (0) and deflate (8) are allowed (FMI 2.0 §2.3, followed by SSP 1.0).",
                             file=display)
        if (info.file_size > RATIO_CHECK_BYTES
                and info.file_size > MAX_COMPRESSION_RATIO * max(info.compress_size, 1)):
            raise SetupError(f"archive member '{name}' expands {info.file_size / max(info.compress_size, 1):.0f}"
                             f" times (limit {MAX_COMPRESSION_RATIO}:1 for members over "
                             f"{_size_text(RATIO_CHECK_BYTES)}): a zip bomb.", file=display)
        declared += info.file_size
        if declared > limit:
            raise SetupError(f"the archive would expand to more than the limit of {_size_text(limit)} "
                             f"({limit} bytes, {source}) at member '{name}' (declared sizes add up to "
                             f"{_size_text(declared)}).", file=display, hint=_limit_hint())


def _extract_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path, dest: Path, total: int,
                    limit: int, source: str) -> int:
    """Copy one member in chunks, counting the bytes really written; returns the new total."""
    target = _target(dest, info.filename)
    if info.is_dir():
        target.mkdir(parents=True, exist_ok=True)
        return total
    target.parent.mkdir(parents=True, exist_ok=True)
    written = 0
    try:
        with archive.open(info) as src, open(target, "wb") as out:
            while chunk := src.read(_CHUNK):
                written += len(chunk)
                if written > info.file_size:
                    raise SetupError(f"archive member '{info.filename}' holds more than the "
                                     f"{info.file_size} bytes its header declares; refusing to extract it.",
                                     file=str(path))
                if total + written > limit:
                    raise SetupError(f"the archive expands to more than the limit of {_size_text(limit)} "
                                     f"({limit} bytes, {source}) while extracting member '{info.filename}'.",
                                     file=str(path), hint=_limit_hint())
                out.write(chunk)
    except (zipfile.BadZipFile, zlib.error, EOFError) as e:
        raise SetupError(f"archive member '{info.filename}' is corrupt ({e}).", file=str(path)) from None
    except OSError as e:
        raise SetupError(f"cannot extract archive member '{info.filename}' ({e.strerror or e}).",
                         file=str(path)) from None
    return total + written


# --------------------------------------------------------------------------- names of files we write

#: characters no file name may hold: path separators (``/``, and ``\\`` of Windows) and the
#: other characters Windows refuses in names (``:`` also names drives and alternate streams)
NAME_FORBIDDEN = frozenset('/\\:<>"|?*')
#: device names Windows reserves, with any extension (``con.csv`` is the console there)
WINDOWS_DEVICES = frozenset({"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)),
                             *(f"LPT{i}" for i in range(10))})
#: the most bytes a name may have, leaving room under the usual 255 for the suffixes cosim adds
#: (``.csv.journal``, ``.part``, ``.lock``)
MAX_NAME_BYTES = 200


def file_name(name: str, *, what: str, file: str | None = None, element: str | None = None,
              hint: str | None = None) -> str:
    """``name`` if it is a plain file name, portable to Windows, macOS and Linux; else a
    `SetupError` naming ``what`` (e.g. "the system name"), ``file`` and ``element``.

    A name taken from text cosim does not control (an SSD's system name, a parameter set's
    name, a file name a sweep worker returns, a regression reference) goes through here
    before it is joined to a folder, so it can never be a path: refused are the empty name,
    ``.`` and ``..``, separators (``/``, ``\\``), ``:`` and the other characters Windows
    forbids, NUL and every control character, Windows device names (``CON``, ``NUL.csv``,
    ``com1``, ...) and names longer than `MAX_NAME_BYTES` bytes in UTF-8.
    """
    problem = _name_problem(name)
    if problem is not None:
        raise SetupError(f"{what} {name!r} cannot be a file name: {problem}. Results are written under a "
                         "name, never a path.", file=file, element=element, hint=hint)
    return name


def _name_problem(name: str) -> str | None:
    if not isinstance(name, str):   # a worker's reply can hold anything
        return f"it is a {type(name).__name__}, not text"
    if not name:
        return "it is empty"
    if name in (".", ".."):
        return "it names a folder"
    bad = sorted({c for c in name if c in NAME_FORBIDDEN or ord(c) < 32 or ord(c) == 127})
    if bad:
        return f"it holds {', '.join(repr(c) for c in bad)}"
    if name.split(".", 1)[0].rstrip(" ").upper() in WINDOWS_DEVICES:
        return "it is a device name on Windows"
    size = len(name.encode("utf-8", "surrogateescape"))
    if size > MAX_NAME_BYTES:
        return f"it is {size} bytes long, more than {MAX_NAME_BYTES}"
    return None


# --------------------------------------------------------------------------- writing results

#: suffix of the file a result is written to before it is renamed into place
PART_SUFFIX = ".part"
#: suffix of the lock file beside an output (`lock_output`)
LOCK_SUFFIX = ".lock"


def partial_path(path: str | Path) -> Path:
    """Where ``path`` is written before it is complete: ``<name>.part`` in the same folder (so
    the rename that puts it in place is atomic)."""
    path = Path(path)
    return path.with_name(path.name + PART_SUFFIX)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield `partial_path` of ``path`` to write; when the block ends normally it replaces
    ``path`` in one ``os.replace``, when it raises it is deleted and ``path`` is untouched.
    A reader sees the old file or the new one, never half of one."""
    part = partial_path(path)
    try:
        yield part
        os.replace(part, path)
    except BaseException:
        part.unlink(missing_ok=True)
        raise


def write_atomic(path: str | Path, data: bytes | str) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through `atomic_path`."""
    with atomic_path(path) as part:
        part.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)


def lock_path(output: str | Path) -> Path:
    """The lock file of an output: ``<output>.lock`` beside it."""
    output = Path(output)
    return output.with_name(output.name + LOCK_SUFFIX)


class OutputLock:
    """An exclusive ``flock`` on an output's lock file, which holds the holder's pid.

    Released by `release` (or leaving the ``with`` block): the file is deleted, then closed.
    A process that dies releases it with its last descriptor (a forked child keeps it while
    it lives); a lock file left by a killed process is taken over, never an obstacle.
    """

    def __init__(self, path: Path, fd: int):
        self.path = path
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is not None:
            self.path.unlink(missing_ok=True)   # while still held: no one can lock the old file meanwhile
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> OutputLock:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.release()


def lock_output(output: str | Path, *, option: str = "--output") -> OutputLock:
    """Take ``<output>.lock`` (making the folder), or a `SetupError` naming the output, the
    process holding it and ``option`` when another process writes the same output."""
    import fcntl   # POSIX (as the supervisor's fork is); imported here so reading SSP files needs none

    output = Path(output)
    path = lock_path(output)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as e:
                holder = _holder(fd)
                os.close(fd)
                if e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                    raise
                raise SetupError(f"{output} is being written by {holder} (it holds the lock {path}); "
                                 "wait for it to end or choose another output.", element=option) from None
            if _same_file(fd, path):   # not deleted by a holder releasing it since we opened it
                break
            os.close(fd)
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        except OSError:
            os.close(fd)
            raise
    except OSError as e:
        raise SetupError(f"cannot take the lock {path} ({e.strerror or e}).", element=option) from None
    return OutputLock(path, fd)


def _holder(fd: int) -> str:
    text = os.pread(fd, 32, 0).decode(errors="replace").strip()
    return f"process {text}" if text.isdigit() else "another process"


def _same_file(fd: int, path: Path) -> bool:
    try:
        now = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino)
