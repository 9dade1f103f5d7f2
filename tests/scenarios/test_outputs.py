"""Output paths are checked before anything is instantiated, and a full disk ends a run
cleanly (issue 17): before, `cosim run S -o S/SystemStructure.ssd` and `cosim pack S -o
S/SystemStructure.ssd` destroyed the scenario, and a bad -o, JSON or --plot path was a
traceback, some after the whole run."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.record.results import read
from runhelpers import refused as _refused

SCENARIO = Path("ssp/pid_fopdt")


@pytest.fixture
def scenario(tmp_path) -> Path:
    import shutil
    return Path(shutil.copytree(SCENARIO, tmp_path / "pid_fopdt"))




@pytest.mark.parametrize("command", ["run", "pack"])
def test_the_scenario_s_own_files_are_never_written_over(scenario, capsys, command):
    before = {p: p.read_bytes() for p in scenario.rglob("*") if p.is_file()}
    ssd = scenario / "SystemStructure.ssd"
    from cosim.plan.prepare import prepare
    with prepare(scenario) as prepared:
        fmu = prepared.plan.fmus["controller"].path  # found by the FMU provider (build/fmus), not in the folder
    fmu_bytes = fmu.read_bytes()
    for target in (ssd, scenario / "controller.ssv", fmu):
        err = _refused(capsys, command, str(scenario), "-o", str(target))
        assert "one of the scenario's own files" in err or "must end in" in err
    if command == "run":  # a legal suffix: refused for what the file is
        ssd_csv = ssd.with_suffix(".csv")
        err = _refused(capsys, "run", str(scenario), "-q", "-o", str(ssd_csv.with_name("x.csv")), "--plot",
                       str(ssd))
        assert "plot name must end in" in err
    assert {p: p.read_bytes() for p in scenario.rglob("*") if p.is_file()} == before
    assert fmu.read_bytes() == fmu_bytes


def test_an_archive_is_not_packed_onto_itself(scenario, tmp_path, capsys):
    archive = tmp_path / "a.ssp"
    assert main(["pack", str(scenario), "-o", str(archive)]) == 0
    data = archive.read_bytes()
    err = _refused(capsys, "pack", str(archive), "-o", str(archive))
    assert "one of the scenario's own files" in err and archive.read_bytes() == data
    err = _refused(capsys, "run", str(archive), "-o", str(archive.with_suffix(".csv")), "-q", "--stop", "1",
                   "--plot", str(tmp_path / "p.xyz"))
    assert "plot name must end in" in err and ".png" in err


@pytest.mark.parametrize("case", ["folder", "json folder", "file as parent", "not writable", "suffix"])
def test_bad_result_paths_are_refused_before_the_run(scenario, tmp_path, capsys, case):
    target = tmp_path / "r.csv"
    if case == "folder":
        target.mkdir()
    elif case == "json folder":
        target.with_suffix(".json").mkdir()
    elif case == "file as parent":
        (tmp_path / "f").write_text("x")
        target = tmp_path / "f" / "sub" / "r.csv"
    elif case == "not writable":
        if os.geteuid() == 0:
            pytest.skip("root writes anywhere: os.access is always true")
        (tmp_path / "ro").mkdir(mode=0o500)
        target = tmp_path / "ro" / "r.csv"
    else:
        target = tmp_path / "r.txt"
    err = _refused(capsys, "run", str(scenario), "-q", "-o", str(target))
    assert "--output" in err
    assert not target.with_suffix(".json").is_file()  # nothing ran


def test_a_missing_result_folder_is_made(scenario, tmp_path):
    target = tmp_path / "new" / "deeper" / "r.csv"
    assert main(["run", str(scenario), "-q", "--stop", "1", "-o", str(target)]) == 0
    assert len(read(target)) > 1


def test_a_full_disk_ends_the_run_cleanly_and_keeps_what_fitted(scenario, small_disk, capsys):
    target = small_disk / "r.csv"
    code = main(["run", str(scenario), "-q", "--stop", "100000", "-o", str(target)])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err and "No space left on device" in err, err
    assert not (small_disk / "r.csv.journal").exists()  # the journal is removed; it would only fill the disk
    res = read(target)  # every line left is whole
    assert len(res) >= 1 and list(res["time"]) == pytest.approx([0.1 * k for k in range(len(res))], abs=1e-9)
    if target.with_suffix(".json").exists():
        assert json.loads(target.with_suffix(".json").read_text())["status"] == "failed"


def test_cosim_report_checks_its_page_as_run_report_does(scenario, tmp_path, capsys):
    """`cosim report RESULT -o X` refuses X before reading anything, as `cosim run --report` does:
    the result itself or its JSON (destroyed before), a folder, a wrong suffix, a file as a folder."""
    result = tmp_path / "r.csv"
    assert main(["run", str(scenario), "-q", "--stop", "2", "-o", str(result)]) == 0
    capsys.readouterr()
    kept = {p: p.read_bytes() for p in (result, result.with_suffix(".json"))}
    (tmp_path / "file").write_text("")
    for target, reason in [(result, "must end in .html or .htm"), (result.with_suffix(".json"), "must end in"),
                           (tmp_path, "must end in"), (tmp_path / "file" / "r.html", "is a file, not a folder")]:
        assert reason in _refused(capsys, "report", str(result), "-o", str(target))
    (tmp_path / "page.html").mkdir()
    assert "is a folder" in _refused(capsys, "report", str(result), "-o", str(tmp_path / "page.html"))
    odd = tmp_path / "odd.html"   # a CSV named .html: its default page would be the result itself
    odd.write_bytes(result.read_bytes())
    assert "one of the result's own files" in _refused(capsys, "report", str(odd))
    assert odd.read_bytes() == result.read_bytes()
    assert {p: p.read_bytes() for p in kept} == kept
    assert main(["report", str(result), "-o", str(tmp_path / "new" / "r.html")]) == 0
    assert (tmp_path / "new" / "r.html").stat().st_size > 0
