"""Names and files that broke the tools (issue 17): component names a CSV quotes (issue 26),
result files compare/metrics must refuse with exit 2, a file with an ``inf`` that differed
from itself, a closed pipe, and a NUL byte in an FMU source inside an .ssp."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from runhelpers import cli_exit as _exit
from cosim.record.results import read
import shutil
import subprocess
import sys
import zipfile
from cosim.cli import main
from cosim.record.results import read, write




def _result(tmp_path: Path, name: str, columns: dict) -> Path:
    path = tmp_path / name
    header = ",".join(f'"{c}"' for c in columns)
    rows = zip(*columns.values())
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path


def test_a_file_without_a_time_column_is_refused(tmp_path, capsys):
    bad = _result(tmp_path, "bad.csv", {"t": [0, 1], "y": [0, 1]})
    assert "no 'time' column" in _exit(capsys, 2, "compare", str(bad), str(bad))
    assert "no 'time' column" in _exit(capsys, 2, "metrics", str(bad), "--signal", "y", "--setpoint", "y")


@pytest.mark.parametrize("content", ['"time","y"\n', "", '"time","y"\n1,0\n0,1\n', '"time","y"\nnan,0\n'])
def test_empty_or_broken_result_files_are_refused(tmp_path, capsys, content):
    bad = tmp_path / "bad.csv"
    bad.write_text(content)
    _exit(capsys, 2, "compare", str(bad), str(bad))


def test_a_result_with_infinities_agrees_with_itself(tmp_path, capsys):
    path = _result(tmp_path, "r.csv", {"time": [0, 1, 2], "y": [1.0, "inf", "-inf"]})
    assert np.isinf(read(path)["y"][1:]).all()
    _exit(capsys, 0, "compare", str(path), str(path))
    other = _result(tmp_path, "o.csv", {"time": [0, 1, 2], "y": [1.0, "inf", "inf"]})
    assert "1 of" not in _exit(capsys, 1, "compare", str(path), str(other))


@pytest.mark.parametrize("argv, text", [(["--t0", "50"], "--t0 50 is outside the result's time range [0, 2]"),
                                        (["--t1", "-1"], "--t1 -1 is outside"),
                                        (["--t0", "1.5", "--t1", "1"], "--t1 1 is not after --t0 1.5")])
def test_metrics_windows_outside_the_result_are_refused(tmp_path, capsys, argv, text):
    path = _result(tmp_path, "r.csv", {"time": [0, 1, 2], "y": [0, 1, 1], "r": [0, 1, 1]})
    assert text in _exit(capsys, 2, "metrics", str(path), "--signal", "y", "--setpoint", "r", *argv)


def test_a_plain_header_reads_as_fmpy_reads_it(tmp_path):
    from fmpy.util import read_csv

    path = _result(tmp_path, "r.csv", {"time": [0, 1, 2], "a.y": [1.5, "-0", "nan"], "b": ["inf", 2, 3]})
    ours, theirs = read(path), read_csv(str(path))
    assert ours.dtype == theirs.dtype
    assert all(np.array_equal(ours[n], theirs[n], equal_nan=True) for n in ours.dtype.names)


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


SCENARIO = Path("ssp/pid_fopdt")


@pytest.mark.pythonfmu
@pytest.mark.parametrize("name", ["pl,ant", 'pl"ant', "pl\nant", 'p"l,\na"n""t'])
def test_a_name_with_commas_quotes_or_line_breaks_is_quoted_in_the_csv(tmp_path, capsys, name):
    """Issue 26 (was refused at run time, naming the CSV, while validate passed it): the header
    quotes it as RFC 4180 does, and cosim's reader reads it back; Parquet carries it too."""
    folder = Path(shutil.copytree(SCENARIO, tmp_path / "s"))
    ssd = folder / "SystemStructure.ssd"
    escaped = name.replace('"', "&quot;").replace("\n", "&#10;").replace("\r", "&#13;")
    ssd.write_text(ssd.read_text().replace('"plant"', f'"{escaped}"'))
    _exit(capsys, 0, "validate", str(folder))
    _exit(capsys, 0, "run", str(folder), "-q", "--stop", "1", "-o", str(tmp_path / "r.csv"))
    _exit(capsys, 0, "run", str(folder), "-q", "--stop", "1", "-o", str(tmp_path / "r.parquet"))
    csv, parquet = read(tmp_path / "r.csv"), read(tmp_path / "r.parquet")
    assert f"{name}.y" in csv.dtype.names and csv.dtype.names == parquet.dtype.names
    assert all(np.array_equal(csv[n], parquet[n]) for n in csv.dtype.names)
    header = (tmp_path / "r.csv").read_text().split('"time",', 1)[1]
    assert '"' + f"{name}.y".replace('"', '""') + '"' in header
    write(csv, tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_bytes() == (tmp_path / "r.csv").read_bytes()
    _exit(capsys, 0, "compare", str(tmp_path / "r.csv"), str(tmp_path / "r.parquet"))


@pytest.mark.pythonfmu
def test_a_closed_pipe_ends_quietly():
    proc = subprocess.run(f"'{sys.executable}' -m cosim.cli info {SCENARIO} | head -1", shell=True,
                          capture_output=True, text=True)
    assert proc.stdout.startswith("system 'pid_fopdt'") and proc.stdout.count("\n") == 1
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr, proc.stderr


@pytest.mark.pythonfmu
def test_a_nul_byte_in_a_source_inside_an_ssp_is_refused(tmp_path, capsys):
    archive = tmp_path / "a.ssp"
    assert main(["pack", str(SCENARIO), "-o", str(archive)]) == 0
    with zipfile.ZipFile(archive) as z:
        members = [(i, z.read(i)) for i in z.infolist()]
    with zipfile.ZipFile(archive, "w") as z:
        for info, data in members:
            if info.filename == "SystemStructure.ssd":
                data = data.replace(b'source="resources/PID.fmu"', b'source="resources/PID%00.fmu"')
            z.writestr(info, data)
    err = _exit(capsys, 2, "validate", str(archive))
    assert "NUL byte" in err and "controller" in err
