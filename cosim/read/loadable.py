"""An FMU file checked as `run` will load it, without loading it: what `cosim validate` needs
to say that `run` can (issue 17: an FMU without a binary for this platform, a binary that is
not a shared library, a wrong modelIdentifier, bad archive members of an FMU outside an .ssp
and entities in a modelDescription.xml validated, then failed or were expanded).

`check_fmu_file`, before fmpy reads the description: the archive checks of
`cosim.safeio` (names, links, sizes, ratio: what run's extraction refuses) and a DOCTYPE
parsed by the SSD reader's safe parser (fmpy's would expand entities).  `check_library`,
after: the shared library.

FMI 2.0 §2.3 / FMI 3.0 §2.5: the library is ``binaries/<platform>/<modelIdentifier><ext>``
(``linux64``, ``x86_64-linux``: `fmpy.platform`, `fmpy.platform_tuple`).  On Linux it must be
an ELF shared object (``e_type`` ET_DYN) of this machine's class, byte order and architecture
whose dynamic symbol table (``.dynsym``, read from the section headers) defines the FMI
functions the master calls for the FMU's interface.
"""
from __future__ import annotations

import platform
import struct
import sys
import zipfile
from pathlib import Path

import fmpy

from ..errors import SetupError
from .fmucache import passed, record_pass
from ..safeio import DOCTYPE_MARKS, check_archive, max_unpacked_bytes, parse_xml_bytes

#: the functions the master calls, per interface (cosim.run.instances)
REQUIRED = {
    "fmi2-cs": ("fmi2Instantiate", "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
                "fmi2ExitInitializationMode", "fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2Terminate"),
    "fmi2-me": ("fmi2Instantiate", "fmi2FreeInstance", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
                "fmi2ExitInitializationMode", "fmi2GetDerivatives", "fmi2SetContinuousStates",
                "fmi2GetContinuousStates", "fmi2SetTime", "fmi2GetReal", "fmi2SetReal", "fmi2Terminate"),
    "fmi3-cs": ("fmi3InstantiateCoSimulation", "fmi3FreeInstance", "fmi3EnterInitializationMode",
                "fmi3ExitInitializationMode", "fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3Terminate"),
    "fmi3-me": ("fmi3InstantiateModelExchange", "fmi3FreeInstance", "fmi3EnterInitializationMode",
                "fmi3ExitInitializationMode", "fmi3GetContinuousStateDerivatives", "fmi3SetContinuousStates",
                "fmi3GetContinuousStates", "fmi3SetTime", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3Terminate"),
}
#: ELF e_machine of the architectures this master runs on
_MACHINES = {"x86_64": 62, "AMD64": 62, "aarch64": 183, "arm64": 183}
_ET_DYN, _SHT_DYNSYM = 3, 11


#: the checks passed, by what they depend on (a system of 10 000 copies of one FMU reads it once);
#: across processes, by content (`cosim.read.fmucache.passed`)
_passed: set[tuple] = set()


def _key(path: Path, *rest) -> tuple:
    stat = path.stat()
    return (path.resolve(), stat.st_size, stat.st_mtime_ns, max_unpacked_bytes()[0], *rest)


def check_fmu_file(path: Path, *, file: str, where: str) -> None:
    """What must hold before the FMU's modelDescription.xml is parsed by fmpy."""
    key = _key(path)
    check = f"archive and entities, limit {key[3]}"
    if key in _passed or passed(path, check):
        _passed.add(key)
        return
    if not path.is_dir():
        try:
            check_archive(path, display=str(path))
        except SetupError as e:  # named by the component that refers to it, and the file
            what = (" (it is empty: 0 bytes)" if path.is_file() and path.stat().st_size == 0 else
                    " (it is the SSD itself)" if Path(file).resolve() == path.resolve() else "")
            raise SetupError(f"its FMU {e.file or path} is not a usable FMU archive{what}: {e.detail}", file=file,
                             element=where, hint=e.hint) from None
    _refuse_entities(path, file, where)
    _passed.add(key)
    record_pass(path, check)


def _refuse_entities(path: Path, file: str, where: str) -> None:
    """fmpy's parser expands entities declared in a modelDescription.xml (the billion-laughs
    document): a DOCTYPE is parsed by `cosim.safeio.parse_xml_bytes` first, which refuses
    entity declarations and external DTDs as for SSP documents."""
    display = f"{path.name}!modelDescription.xml"
    try:
        if path.is_dir():
            data = (path / "modelDescription.xml").read_bytes()
        else:
            with zipfile.ZipFile(path) as archive:
                data = archive.read("modelDescription.xml")
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError):
        return  # fmpy reports the missing or unreadable description, with its own words
    if any(mark in data for mark in DOCTYPE_MARKS):
        try:
            parse_xml_bytes(data, display)
        except SetupError as e:
            raise SetupError(e.detail, file=file, element=f"{where}, {display}", hint=e.hint) from None


def library_member(model_identifier: str, kind: str) -> str:
    """The library's path inside the FMU for this platform and interface (``model_identifier``:
    that interface's modelIdentifier)."""
    folder = fmpy.platform_tuple if kind.startswith("fmi3") else fmpy.platform
    return f"binaries/{folder}/{model_identifier}{fmpy.sharedLibraryExtension}"


def check_library(path: Path, model_identifier: str, kind: str, *, file: str, where: str) -> None:
    """Refuse an FMU whose library for this platform is missing, not a shared object of this
    machine, or lacks one of the functions ``kind`` needs."""
    member = library_member(model_identifier, kind)
    key = _key(path, member, kind)
    check = f"library {member} {kind} on {sys.platform} {platform.machine()}, limit {key[3]}"
    if key in _passed or passed(path, check):
        _passed.add(key)
        return
    data = _read_member(path, member, file, where)
    if sys.platform.startswith("linux"):
        exports = _elf_exports(data, path.name, member, file, where)
        missing = [f for f in REQUIRED[kind] if f not in exports]
        if missing:
            raise SetupError(f"{path.name}: {member} does not export {', '.join(missing)} (the FMI functions "
                             "this master calls); is modelIdentifier right?", file=file, element=where)
    _passed.add(key)
    record_pass(path, check)


def _read_member(path: Path, member: str, file: str, where: str) -> bytes:
    if path.is_dir():  # an extracted (folder) FMU
        target = path / member
        names = sorted(p.relative_to(path).as_posix() for p in (path / "binaries").rglob("*")) \
            if (path / "binaries").is_dir() else []
        if target.is_file():
            return target.read_bytes()
    else:
        with zipfile.ZipFile(path) as archive:
            names = sorted(n for n in archive.namelist() if n.startswith("binaries/") and not n.endswith("/"))
            if member in names:
                info = archive.getinfo(member)
                limit, _ = max_unpacked_bytes()
                if info.file_size > limit:
                    raise SetupError(f"{path.name}: {member} expands to {info.file_size} bytes, over the "
                                     f"{limit}-byte limit.", file=file, element=where)
                return archive.read(member)
    raise SetupError(f"{path.name} has no binary for this platform: {member} is missing "
                     f"(binaries: {', '.join(names) if names else 'none'}).", file=file, element=where)


def _elf_exports(data: bytes, fmu: str, member: str, file: str, where: str) -> set[str]:
    """The defined symbols of an ELF shared object's dynamic symbol table."""
    def refuse(why: str) -> SetupError:
        return SetupError(f"{fmu}: {member} is not a shared library this machine can load ({why}).",
                          file=file, element=where)

    if data[:4] != b"\x7fELF":
        raise refuse("not an ELF file")
    if data[4] != 2 or data[5] != 1:
        raise refuse(f"ELF class {data[4]}, byte order {data[5]}; a 64-bit little-endian object is needed")
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    if e_type != _ET_DYN:
        raise refuse(f"ELF type {e_type}, not a shared object (3)")
    expected = _MACHINES.get(platform.machine())
    if expected is not None and e_machine != expected:
        raise refuse(f"ELF machine {e_machine}, this is {platform.machine()} ({expected})")
    try:
        shoff, = struct.unpack_from("<Q", data, 40)
        shentsize, shnum = struct.unpack_from("<HH", data, 58)
        sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
        dynsym = next((s for s in sections if s[1] == _SHT_DYNSYM), None)
        if dynsym is None:
            raise refuse("no dynamic symbol table")
        strtab = sections[dynsym[6]]
        strings = data[strtab[4]:strtab[4] + strtab[5]]
        names = set()
        for offset in range(dynsym[4], dynsym[4] + dynsym[5], 24):
            st_name, _, _, st_shndx = struct.unpack_from("<IBBH", data, offset)
            if st_shndx != 0:  # defined here, not imported
                names.add(strings[st_name:strings.index(b"\0", st_name)].decode(errors="replace"))
        return names
    except (struct.error, IndexError, ValueError):
        raise refuse("truncated or malformed section headers") from None
