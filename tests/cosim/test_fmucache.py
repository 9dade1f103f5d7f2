"""The shared cache of unpacked FMUs (`cosim.read.fmucache`): results as with a fresh unpack, safe
between concurrent processes, a new entry for new content, a broken entry rebuilt."""
from __future__ import annotations

import os
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import SetupError
from cosim.read.fmucache import MARKER, digest, unpacked
from cosim.run.instances import Unzipped

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "benchmarks")]

from native_systems import FAMILIES, build_family, native_system, write_native_system  # noqa: E402
import subprocess
from cosim.read.fmucache import MARKER, digest


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory) -> dict[str, Path]:
    return build_family("c", tmp_path_factory.mktemp("cfmus"))


@pytest.fixture
def fresh(monkeypatch):
    """A process that has looked up no FMU yet (the in-process memo of `Unzipped` emptied)."""
    monkeypatch.setattr(Unzipped, "_dirs", {})
    monkeypatch.setattr(Unzipped, "_tmp", None)
    yield
    Unzipped.release()


def _entries(root: Path) -> list[str]:
    """The unpacked FMUs and temporary folders of a cache (not the verdicts of its checks)."""
    return sorted(p.name for p in root.iterdir() if p.name != "verdicts") if root.exists() else []


def _chain(c_fmus: dict[str, Path], folder: Path) -> Path:
    return write_native_system(native_system(FAMILIES["c"], "chained", 3), c_fmus, folder, 0.05, 1e-3)


def test_a_cached_fmu_gives_the_results_of_a_fresh_unpack(tmp_path, c_fmus, fresh, monkeypatch):
    system = _chain(c_fmus, tmp_path / "ssp")
    monkeypatch.setenv("COSIM_FMU_CACHE", "off")
    fresh_result = cosim.simulate(system, use_providers=False)
    assert Unzipped.folder() is not None   # extracted into this process's folder
    Unzipped.release()
    root = tmp_path / "cache"
    monkeypatch.setenv("COSIM_FMU_CACHE", str(root))
    first = cosim.simulate(system, use_providers=False)
    assert _entries(root) == sorted(digest(p) for p in c_fmus.values())
    monkeypatch.setattr(Unzipped, "_dirs", {})   # another process: the entries are used as they are
    made = {p: p.stat().st_mtime_ns for p in root.rglob("*")}
    again = cosim.simulate(system, use_providers=False)
    assert {p: p.stat().st_mtime_ns for p in root.rglob("*")} == made
    for result in (first, again):
        assert result.dtype.names == fresh_result.dtype.names
        assert all(np.array_equal(result[n], fresh_result[n]) for n in result.dtype.names)


def _zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def test_a_modified_fmu_file_gets_a_new_unpack(tmp_path, c_fmus, fresh, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("COSIM_FMU_CACHE", str(root))
    fmu = tmp_path / "Lag.fmu"
    fmu.write_bytes(c_fmus["Lag"].read_bytes())
    os.utime(fmu, ns=(1_000_000_000, 1_000_000_000))
    before = Path(Unzipped()(fmu))
    assert not (before / "resources" / "table.txt").exists()
    with zipfile.ZipFile(c_fmus["Lag"]) as archive:
        members = {i.filename: archive.read(i) for i in archive.infolist() if not i.is_dir()}
    _zip(fmu, members | {"resources/table.txt": b"1 2 3\n"})   # same path, new content, new mtime
    after = Path(Unzipped()(fmu))
    assert after != before and after.parent.name == digest(fmu)
    assert (after / "resources" / "table.txt").read_bytes() == b"1 2 3\n"
    assert len(_entries(root)) == 2


def test_an_entry_without_its_marker_is_rebuilt(tmp_path, c_fmus):
    root, fmu = tmp_path / "cache", c_fmus["VanDerPol"]
    folder = unpacked(fmu, root)
    library = next(folder.glob("binaries/*/*"))
    (folder.parent / MARKER).unlink()   # a crash or a hand edit: the entry is not known complete
    os.chmod(library, 0o644)
    library.write_bytes(b"broken")
    again = unpacked(fmu, root)
    assert again == folder and (folder.parent / MARKER).is_file()
    with zipfile.ZipFile(fmu) as archive:
        assert library.read_bytes() == archive.read(library.relative_to(folder).as_posix())
    assert _entries(root) == [digest(fmu)]
    assert not library.stat().st_mode & 0o222


def test_a_refused_archive_leaves_no_entry(tmp_path):
    root = tmp_path / "cache"
    bad = _zip(tmp_path / "bad.fmu", {"modelDescription.xml": b"<x/>", "../escape.txt": b"x"})
    with pytest.raises(SetupError, match="escapes the archive"):
        unpacked(bad, root)
    assert _entries(root) == []


def test_the_size_limit_in_force_applies_to_a_cached_entry(tmp_path, c_fmus, monkeypatch):
    root, fmu = tmp_path / "cache", c_fmus["Lag"]
    unpacked(fmu, root)
    monkeypatch.setenv("COSIM_MAX_UNPACKED_BYTES", "100")
    with pytest.raises(SetupError, match="limit"):
        unpacked(fmu, root)


def test_providers_are_asked_only_for_fmus_not_beside_the_ssd_and_once_per_name(tmp_path, c_fmus, monkeypatch):
    """Loading the providers imports their packages (tens of ms of a run's fixed cost)."""
    import cosim.read.resources
    from cosim.read import ssp
    from cosim.read.resources import locate_fmus

    asked: list[str] = []

    def counting_provider(name: str) -> Path | None:
        asked.append(name)
        return c_fmus["Lag"] if name == "Lag.fmu" else None

    monkeypatch.setattr(cosim.read.resources, "providers", lambda: ([counting_provider], []))
    system = _chain(c_fmus, tmp_path / "ssp")   # m1 (VanDerPol) then b2, b3 (Lag)
    structure = ssp.load(system)
    assert set(locate_fmus(structure).values()) == {system / "resources" / "VanDerPol.fmu",
                                                    system / "resources" / "Lag.fmu"}
    assert asked == []
    (system / "resources" / "Lag.fmu").unlink()
    found = locate_fmus(structure)
    assert found["b2"] == found["b3"] == c_fmus["Lag"] and asked == ["Lag.fmu"]


def test_checks_passed_are_kept_by_content_and_failures_are_not(tmp_path, c_fmus, monkeypatch):
    import cosim.read.loadable
    from cosim.read.description import describe_fmu as _describe

    root = tmp_path / "cache"
    monkeypatch.setenv("COSIM_FMU_CACHE", str(root))
    monkeypatch.setattr(cosim.read.loadable, "_passed", set())   # a process that checked nothing yet
    monkeypatch.setattr("cosim.read.description._cache", {})
    fmu = c_fmus["Lag"]
    desc = _describe(fmu, "here", "x.ssd", "any")
    kept = sorted(p.name.split("-")[0] for p in (root / "verdicts").iterdir())
    assert kept == [digest(fmu)] * 3    # archive and entities, FMI schema, library
    monkeypatch.setattr(cosim.read.loadable, "_passed", set())   # another process: the verdicts are used
    monkeypatch.setattr("cosim.read.description._cache", {})
    again = _describe(fmu, "here", "x.ssd", "any")
    assert list(again.variables) == list(desc.variables)
    with zipfile.ZipFile(fmu) as archive:   # the same FMU without its library: refused, every time
        members = {i.filename: archive.read(i) for i in archive.infolist()
                   if not i.is_dir() and not i.filename.startswith("binaries/")}
    broken = _zip(tmp_path / "Lag.fmu", members)
    for _ in range(2):
        with pytest.raises(SetupError, match="no binary for this platform"):
            _describe(broken, "here", "x.ssd", "any")
    assert len(list((root / "verdicts").glob(f"{digest(broken)}-*"))) == 2   # archive and schema, not library


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


_RACE = """
import sys, time
from pathlib import Path
from cosim.read.fmucache import unpacked
go = Path(sys.argv[3])
while not go.exists():
    time.sleep(0.001)
print(unpacked(Path(sys.argv[1]), Path(sys.argv[2])))
"""


@pytest.mark.pythonfmu
def test_concurrent_processes_populating_the_cache_make_one_complete_entry(tmp_path, built_fmus):
    fmu, root, go = built_fmus["PID"], tmp_path / "cache", tmp_path / "go"
    procs = [subprocess.Popen([sys.executable, "-c", _RACE, str(fmu), str(root), str(go)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, cwd=ROOT) for _ in range(4)]
    go.touch()
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0] * 4, [err for _, err in outs]
    entry = root / digest(fmu)
    assert {out.strip() for out, _ in outs} == {str(entry / "fmu")}
    assert _entries(root) == [entry.name]    # no temporary folder left behind
    assert (entry / MARKER).is_file()
    with zipfile.ZipFile(fmu) as archive:
        for info in archive.infolist():
            if not info.is_dir():
                assert (entry / "fmu" / info.filename).read_bytes() == archive.read(info), info.filename
