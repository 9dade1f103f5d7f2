"""`cosim validate` checks the shared library `run` loads, without loading it (issue 17:
an FMU without a binary for this platform, a binary that is not a shared library, or a wrong
modelIdentifier validated, then failed with a traceback at run time)."""
from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from cosim.cli import main
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus, edited_copy

SO = "binaries/linux64/Failing.so"


@pytest.fixture(scope="module")
def failing(tmp_path_factory) -> Path:
    return build_test_fmus(tmp_path_factory.mktemp("binfmus"))["Failing"]


def _with_member(source: Path, target: Path, member: str, data: bytes | None) -> Path:
    """A copy of ``source`` with ``member`` replaced by ``data`` (None: removed)."""
    with zipfile.ZipFile(source) as archive:
        members = [(info, archive.read(info)) for info in archive.infolist()]
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for info, content in members:
            if info.filename == member:
                if data is None:
                    continue
                content = data
            archive.writestr(info, content)
    return target


def _validate(tmp_path: Path, fmu: Path, capsys) -> tuple[int, str]:
    comps = {"f": ("Failing.fmu", {"u": "input", "y": "output"})}
    folder = write_system(tmp_path / "sys", {"Failing.fmu": fmu}, ssd_text("b", comps, []))
    code = main(["validate", str(folder)])
    return code, capsys.readouterr().err


def _so(failing: Path) -> bytes:
    with zipfile.ZipFile(failing) as archive:
        return archive.read(SO)


def test_the_real_library_passes(tmp_path, failing, capsys):
    assert _validate(tmp_path, failing, capsys)[0] == 0


@pytest.mark.parametrize("case, message", [
    ("missing", "has no binary for this platform: binaries/linux64/Failing.so is missing (binaries: "
                "binaries/win64/Failing.dll)"),
    ("text", "is not a shared library this machine can load (not an ELF file)"),
    ("executable", "ELF type 2, not a shared object (3)"),
    ("32-bit", "ELF class 1, byte order 1; a 64-bit little-endian object is needed"),
    ("other machine", "ELF machine 183, this is x86_64 (62)"),
    ("truncated", "truncated or malformed section headers"),
    ("other library", "does not export fmi2Instantiate, fmi2FreeInstance"),
])
def test_a_library_run_could_not_load_is_refused(tmp_path, failing, capsys, case, message):
    import platform
    if platform.machine() != "x86_64":
        pytest.skip("the cases are written for an x86_64 machine")
    so = _so(failing)
    data = {"missing": None, "text": b"not a library\n",
            "executable": so[:16] + b"\x02\x00" + so[18:],
            "32-bit": so[:4] + b"\x01" + so[5:],
            "other machine": so[:18] + (183).to_bytes(2, "little") + so[20:],
            "truncated": so[:4096],
            "other library": Path("/lib/x86_64-linux-gnu/libm.so.6").read_bytes()}[case]
    fmu = _with_member(failing, tmp_path / "Failing.fmu", SO, data)
    code, err = _validate(tmp_path, fmu, capsys)
    assert code == 2 and "Traceback" not in err and message in err, err


def test_a_wrong_model_identifier_is_refused(tmp_path, failing, capsys):
    fmu = edited_copy(failing, tmp_path / "Failing.fmu",
                      lambda text: text.replace('modelIdentifier="Failing"', 'modelIdentifier="Failng"'))
    code, err = _validate(tmp_path, fmu, capsys)
    assert code == 2 and "binaries/linux64/Failng.so is missing" in err and "Traceback" not in err


@pytest.mark.parametrize("doctype, message", [
    ('<!DOCTYPE fmiModelDescription [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>',
     "entity declarations are not allowed"),
    ('<!DOCTYPE fmiModelDescription SYSTEM "file:///etc/passwd">', "names an external DTD")])
def test_entities_in_a_model_description_are_refused(tmp_path, failing, capsys, doctype, message):
    """issue 17: fmpy expanded an entity declared in a modelDescription.xml (the SSD reader refused them)."""
    def edit(text: str) -> str:
        head, _, body = text.partition("?>")
        return head + "?>" + doctype + body.replace('description="', 'description="&b;' if "ENTITY" in doctype
                                                    else 'description="', 1)
    fmu = edited_copy(failing, tmp_path / "Failing.fmu", edit)
    code, err = _validate(tmp_path, fmu, capsys)
    assert code == 2 and message in err and "Failing.fmu!modelDescription.xml" in err and "Traceback" not in err


@pytest.mark.parametrize("member, message", [("../../evil.txt", "evil.txt"), ("/abs.txt", "abs.txt")])
def test_a_scenario_folder_fmu_gets_every_archive_check_at_validate(tmp_path, failing, capsys, member, message):
    """issue 17: an FMU in a scenario folder (not in an .ssp) was checked only when run extracted it."""
    fmu = tmp_path / "Failing.fmu"
    _with_member(failing, fmu, "none", None)
    with zipfile.ZipFile(fmu, "a") as archive:
        archive.writestr(member, "x")
    code, err = _validate(tmp_path, fmu, capsys)
    assert code == 2 and message in err and "Traceback" not in err, err


def test_a_symbolic_link_member_is_refused_at_validate(tmp_path, failing, capsys):
    import stat
    fmu = tmp_path / "Failing.fmu"
    _with_member(failing, fmu, "none", None)
    with zipfile.ZipFile(fmu, "a") as archive:
        info = zipfile.ZipInfo("resources/link")
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
        archive.writestr(info, "/etc/passwd")
    code, err = _validate(tmp_path, fmu, capsys)
    assert code == 2 and "is a symbolic link" in err, err
