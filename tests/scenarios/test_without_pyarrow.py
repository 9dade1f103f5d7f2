"""Issue 27: pyarrow is the ``parquet`` extra; without it a CSV run writes the same file and
whatever needs Parquet says which extra to install (exit status 2); a sweep runs and writes its
``sweep.csv`` (no ``sweep.parquet``).

Each case runs ``cosim`` in a fresh interpreter where ``import pyarrow`` fails
(``sys.modules["pyarrow"] = None``), as in an environment installed without the extra.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.sweep import read_table

pytest.importorskip("pyarrow")

ROOT = Path(__file__).resolve().parents[2]

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


def _without_pyarrow_everywhere(folder: Path) -> dict[str, str]:
    """An environment in which no Python started from it, the sweep's spawned workers too, can
    import pyarrow: a ``sitecustomize`` on PYTHONPATH blocks it before anything runs."""
    folder.mkdir()
    (folder / "sitecustomize.py").write_text("import sys\nsys.modules['pyarrow'] = None\n")
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(folder), str(ROOT)])}


def test_a_sweep_without_pyarrow_writes_sweep_csv_and_a_rerun_skips_its_runs(tmp_path, built_fmus):
    env = _without_pyarrow_everywhere(tmp_path / "site")
    blocked = subprocess.run([sys.executable, "-c", "import pyarrow"], env=env, capture_output=True, text=True)
    assert blocked.returncode == 1 and "ModuleNotFoundError" in blocked.stderr
    out = tmp_path / "s"
    args = [sys.executable, "-c", "import sys; from cosim.cli import main; sys.exit(main(sys.argv[1:]))", "sweep",
            str(ROOT / "ssp" / "pid_fopdt"), "--set", "controller.Kc=4,6", "--stop", "60", "--metrics", "plant.y:setpoint.y", "--workers", "2", "-o", str(out)]
    first = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert "2 runs (2 ran now, 0 already done and skipped, 0 failed); table " in first.stdout, first.stdout
    assert (out / "sweep.csv").is_file() and not (out / "sweep.parquet").exists()
    assert sorted(p.suffix for p in (out / "runs").iterdir()) == [".csv"] * 2 + [".json"] * 2 + [".ssv"] * 2
    table = (out / "sweep.csv").read_bytes()
    again = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "2 runs (0 ran now, 2 already done and skipped, 0 failed)" in again.stdout, again.stdout
    assert (out / "sweep.csv").read_bytes() == table and not (out / "sweep.parquet").exists()
    rows = read_table(out / "sweep.csv")
    assert [(r["controller.Kc"], r["status"]) for r in rows] == [("4", "completed"), ("6", "completed")]
    assert all(float(r["plant.y:overshoot"]) > 0 for r in rows)
