"""Issue 27: pyarrow is the ``parquet`` extra; without it a CSV run writes the same file and
whatever needs Parquet says which extra to install (exit status 2).

Each case runs ``cosim`` in a fresh interpreter where ``import pyarrow`` fails
(``sys.modules["pyarrow"] = None``), as in an environment installed without the extra.
"""
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pyarrow")

WITHOUT_PYARROW = ("import sys; sys.modules['pyarrow'] = None; from cosim.cli import main; "
                   "sys.exit(main(sys.argv[1:]))")


def _cosim(*args: str, pyarrow: bool) -> subprocess.CompletedProcess:
    code = WITHOUT_PYARROW if not pyarrow else WITHOUT_PYARROW.replace("sys.modules['pyarrow'] = None; ", "")
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300)


def test_a_csv_run_without_pyarrow_writes_the_bytes_of_one_with_it(tmp_path, built_fmus):
    files = {}
    for pyarrow in (True, False):
        out = tmp_path / f"pyarrow_{pyarrow}.csv"
        done = _cosim("run", "ssp/pid_fopdt", "--stop", "60", "-o", str(out), "-q", pyarrow=pyarrow)
        assert done.returncode == 0, done.stderr
        files[pyarrow] = out.read_bytes()
    assert files[False] == files[True]
    assert files[False].count(b"\n") == 602


def test_a_parquet_run_without_pyarrow_names_the_extra(tmp_path, built_fmus):
    out = tmp_path / "r.parquet"
    done = _cosim("run", "ssp/pid_fopdt", "--stop", "1", "-o", str(out), pyarrow=False)
    assert done.returncode == 2
    assert "pip install 'greyfmu[parquet]'" in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()


def test_reading_a_parquet_result_without_pyarrow_names_the_extra(tmp_path, built_fmus):
    out = tmp_path / "r.parquet"
    assert _cosim("run", "ssp/pid_fopdt", "--stop", "1", "-o", str(out), "-q", pyarrow=True).returncode == 0
    done = _cosim("metrics", str(out), "--signal", "plant.y", "--setpoint", "setpoint.y", pyarrow=False)
    assert done.returncode == 2
    assert "pip install 'greyfmu[parquet]'" in done.stderr and str(out) in done.stderr


def test_a_sweep_without_pyarrow_names_the_extra(tmp_path, built_fmus):
    done = _cosim("sweep", "ssp/pid_fopdt", "--set", "setpoint.final=1,2", "--stop", "1", "-o",
                  str(tmp_path / "s"), pyarrow=False)
    assert done.returncode == 2, done.stderr
    assert "pip install 'greyfmu[parquet]'" in done.stderr and "Traceback" not in done.stderr
