"""A full disk while the results are written (issue 26, item 3): one message naming the file
that could not be written and saying the disk is full, exit 1, no traceback (Arrow's error
named no file: "Error writing bytes to file ... No space left on device")."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.record.results import read
from ssdgen import ssd_text, write_system


@pytest.fixture
def system(tmp_path, twin_fmus) -> Path:
    components = {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("pair", components, [("step", "y", "gain", "u")], stop=2.0, step=0.5)
    return write_system(tmp_path / "pair", {"Step.fmu": twin_fmus["Step"], "Gain.fmu": twin_fmus["Gain"]}, text)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
@pytest.mark.parametrize("suffix, arrow", [(".csv", True), (".csv", False), (".parquet", True)])
def test_a_result_on_a_full_device_is_named(tmp_path, system, capsys, monkeypatch, suffix, arrow):
    """``arrow`` False: the CSV writer used without pyarrow (issue 27)."""
    from cosim.record import observers

    monkeypatch.setattr(observers, "ARROW_CSV", arrow)
    target = tmp_path / f"full{suffix}"
    (tmp_path / f"full{suffix}.part").symlink_to("/dev/full")  # results are written there, then renamed
    code = main(["run", str(system), "-q", "-o", str(target)])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err, err
    assert f"cosim: the run failed (output_error): {target}: the results cannot be written: the disk is full " in err
    assert "Error writing bytes" not in err and err.count("cosim:") == 1


def test_a_disk_that_fills_mid_run_is_named(system, small_disk, capsys):
    target = small_disk / "r.csv"
    code = main(["run", str(system), "-q", "--stop", "100000", "--step", "0.1", "-o", str(target)])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err, err
    failed = re.search(r"cosim: the run failed \(output_error\): (\S+): writing the results failed after (\d+) rows: the disk is full "
                       r"\(No space left on device\)", err)
    assert failed, err
    assert Path(failed.group(1)) in (target, small_disk / "r.csv.journal")  # whichever could not grow first
    rows = len(read(target))
    assert 1 <= rows <= int(failed.group(2))
    if target.with_suffix(".json").exists():
        assert json.loads(target.with_suffix(".json").read_text())["status"] == "failed"
