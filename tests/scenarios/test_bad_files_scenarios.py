"""The tests of tests/cosim/test_bad_files.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from runhelpers import cli_exit as _exit
from cosim.record.results import read, write


SCENARIO = Path("ssp/pid_fopdt")




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


def test_a_closed_pipe_ends_quietly():
    proc = subprocess.run(f"'{sys.executable}' -m cosim.cli info {SCENARIO} | head -1", shell=True,
                          capture_output=True, text=True)
    assert proc.stdout.startswith("system 'pid_fopdt'") and proc.stdout.count("\n") == 1
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr, proc.stderr


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
