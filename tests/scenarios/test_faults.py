"""Faults of the process running the master (issue 17): a crashing FMU (abort, segfault,
_exit) loses no recorded row, SIGINT/SIGTERM stop at the next communication point, and
``--timeout`` ends a slow or hung run; each with the CSV, the JSON's status and no traceback.

`cosim run` runs in a subprocess here (a crash must not take the test process with it); the
FMU is tests/fmus/Faulty.py, a real pythonfmu FMU whose do_step does the fault.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pythonfmu.builder import FmuBuilder

from cosim.record.results import read
from ssdgen import ssd_text, write_system

FAULTY = Path(__file__).parents[1] / "fmus" / "Faulty.py"


@pytest.fixture(scope="module")
def faulty(tmp_path_factory) -> Path:
    return Path(FmuBuilder.build_FMU(FAULTY, dest=tmp_path_factory.mktemp("faulty"), needsExecutionTool="false"))


def _scenario(tmp_path: Path, faulty: Path, fault: int, fault_time: float, stop: float = 20.0,
              step: float = 0.5, **extra) -> Path:
    comps = {"f": ("Faulty.fmu", {"y": "output"})}
    params = {"f": {"fault": fault, "fault_time": fault_time, **extra}}
    return write_system(tmp_path / "sys", {"Faulty.fmu": faulty},
                        ssd_text("faulty", comps, [], stop=stop, step=step, parameters=params))


def _cosim(tmp_path: Path, *argv: str) -> subprocess.Popen:
    env = dict(os.environ, TMPDIR=str(tmp_path / "tmp"), COSIM_FMU_CACHE="off")  # extraction in TMPDIR
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return subprocess.Popen([sys.executable, "-m", "cosim.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _leftovers(tmp_path: Path) -> list[str]:
    return sorted(p.name for p in (tmp_path / "tmp").iterdir())


@pytest.mark.parametrize("fault, killer", [(1, "SIGABRT"), (2, "SIGSEGV"), (3, "exited with status 3")])
def test_a_crashing_fmu_loses_no_row(tmp_path, faulty, fault, killer):
    folder = _scenario(tmp_path, faulty, fault, fault_time=5.0)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert "Traceback" not in err and killer in err and "11 rows recovered" in err
    res = read(csv)
    assert list(res["time"]) == pytest.approx([0.5 * k for k in range(11)])  # every step before t = 5
    assert list(res["f.y"]) == pytest.approx([0.5 * k for k in range(11)])
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "crashed" and killer in meta["message"] and meta["last_time"] == 5.0
    assert meta["error"] == "run_process_lost"
    assert meta["samples"] == 11 and meta["components"]["f"]["fmu"].endswith("Faulty.fmu")
    assert not csv.with_name("out.csv.journal").exists()
    assert _leftovers(tmp_path) == []  # the child's cosim-fmu-* folder is removed by the parent


def test_a_crash_in_a_parquet_run_is_recovered_too(tmp_path, faulty):
    folder = _scenario(tmp_path, faulty, 1, fault_time=2.0)
    out = tmp_path / "out.parquet"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(out))
    proc.communicate(timeout=120)
    assert proc.returncode == 1
    assert list(read(out)["time"]) == pytest.approx([0, 0.5, 1.0, 1.5, 2.0])


def _wait_for_rows(csv: Path, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + 60
    part = csv.with_name(csv.name + ".part")  # written there until the run ends (cosim.safeio.atomic_path)
    while not (part.exists() and part.stat().st_size > 200):  # the header and a flushed row or more
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_stops_at_the_next_communication_point(tmp_path, faulty, signum, code):
    folder = _scenario(tmp_path, faulty, 5, fault_time=0.0, stop=1000.0, step=0.1, delay=0.01)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv))
    _wait_for_rows(csv, proc)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and f"stopped by {signum.name}" in err
    meta = json.loads(csv.with_suffix(".json").read_text())
    res = read(csv)
    assert meta["status"] == "interrupted" and 0 < meta["last_time"] < 1000
    assert res["time"][-1] == pytest.approx(meta["last_time"]) and len(res) == round(meta["last_time"] / 0.1) + 1
    assert _leftovers(tmp_path) == []


def test_timeout_stops_a_slow_run(tmp_path, faulty):
    folder = _scenario(tmp_path, faulty, 5, fault_time=0.0, stop=1000.0, step=0.1, delay=0.01)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv), "--timeout", "1.5")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "Traceback" not in err and "stopped by SIGALRM" in err
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "timeout" and len(read(csv)) == round(meta["last_time"] / 0.1) + 1


def test_timeout_kills_a_hung_fmu_call_and_keeps_the_rows(tmp_path, faulty):
    folder = _scenario(tmp_path, faulty, 4, fault_time=3.0)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv), "--timeout", "1")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "Traceback" not in err and "did not stop within 2 s" in err
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "timeout" and meta["last_time"] == 3.0
    assert list(read(csv)["time"]) == pytest.approx([0, 0.5, 1, 1.5, 2, 2.5, 3])
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf"])
def test_timeout_must_be_a_positive_number(tmp_path, faulty, value):
    folder = _scenario(tmp_path, faulty, 0, fault_time=0.0)
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(tmp_path / "o.csv"), "--timeout", value)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "--timeout" in err and "Traceback" not in err


def test_folders_left_by_a_dead_process_are_removed_by_the_next_run(tmp_path, faulty):
    """An API run killed outright (no supervising parent) leaves its cosim-fmu-* and
    cosim-ssp-* folders; the next extraction removes those of processes that are gone."""
    folder = _scenario(tmp_path, faulty, 0, fault_time=0.0, stop=1.0)
    (tmp_path / "tmp").mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = [tmp_path / "tmp" / f"cosim-fmu-{dead.pid}-abc", tmp_path / "tmp" / f"cosim-ssp-{dead.pid}-abc"]
    for f in stale:
        (f / "0").mkdir(parents=True)
    alive = tmp_path / "tmp" / f"cosim-fmu-{os.getpid()}-mine"  # a live process's folder stays
    alive.mkdir()
    archive = tmp_path / "f.ssp"
    assert _cosim(tmp_path, "pack", str(folder), "-o", str(archive)).wait(timeout=120) == 0
    proc = _cosim(tmp_path, "run", str(archive), "-q", "-o", str(tmp_path / "r.csv"))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert _leftovers(tmp_path) == [alive.name]


def test_a_journal_left_by_a_crashed_api_run_is_recovered(tmp_path, faulty):
    """`cosim.simulate` has no supervising parent: the journal stays, and `recover` writes the
    result files from it with status 'crashed' (none of the 11 completed rows lost)."""
    from cosim.record.journal import journal_path, recover

    folder = _scenario(tmp_path, faulty, 1, fault_time=5.0)
    out = tmp_path / "api.parquet"
    code = f"import cosim; cosim.simulate({str(folder)!r}, output={str(out)!r})"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, TMPDIR=str(tmp_path), COSIM_FMU_CACHE="off"))
    assert proc.returncode == -signal.SIGABRT
    journal = journal_path(out)
    assert journal.exists()
    path, rows = recover(journal, message="found after the run")
    assert path == out.resolve() and rows == 11 and not journal.exists()
    assert list(read(out)["f.y"]) == pytest.approx([0.5 * k for k in range(11)])
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "crashed" and meta["message"] == "found after the run"
    assert not list(tmp_path.glob("cosim-fmu-*"))  # the crashed process's extraction folder too


def _wait_for_journal_rows(journal: Path, rows: int, proc: subprocess.Popen) -> None:
    """Until the run's journal holds ``rows`` rows (the CSV gets them only at a flush)."""
    from cosim.record.journal import read_journal

    deadline = time.monotonic() + 60
    while True:
        assert proc.poll() is None and time.monotonic() < deadline
        try:
            if len(read_journal(journal)[1]) >= rows:
                return
        except (OSError, ValueError):
            pass
        time.sleep(0.05)


@pytest.mark.parametrize("second", [True, False], ids=["second-sigint", "grace"])
def test_sigint_abandons_a_hung_fmu_call_and_keeps_the_rows(tmp_path, faulty, second):
    """Issue 26: an FMU hung in fmi2DoStep; SIGINT asks the run to stop, and a second SIGINT (or
    `INTERRUPT_GRACE` s without the run gone) abandons the call: every completed row and the
    JSON are written, exit 130."""
    from cosim.run.supervisor import INTERRUPT_GRACE

    folder = _scenario(tmp_path, faulty, 4, fault_time=3.0, stop=25.0)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv))
    _wait_for_journal_rows(tmp_path / "out.csv.journal", 7, proc)  # t = 0 .. 3, then the hang
    proc.send_signal(signal.SIGINT)
    if second:
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "stopped by SIGINT" in err and "7 rows recovered" in err
    assert ("a second SIGINT abandoned it" if second else f"abandoned {INTERRUPT_GRACE:g} s after the SIGINT") in err
    assert list(read(csv)["time"]) == pytest.approx([0, 0.5, 1, 1.5, 2, 2.5, 3])
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and meta["last_time"] == 3.0 and meta["samples"] == 7
    assert not csv.with_name("out.csv.journal").exists()
    assert _leftovers(tmp_path) == []


def _children(pid: int) -> list[int]:
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def _gone(pid: int) -> bool:
    """Ended (a zombie waiting for init to reap it counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("fault, status_rows", [(5, None), (4, 7)], ids=["stepping", "hung"])
def test_the_run_dies_with_its_killed_parent(tmp_path, faulty, fault, status_rows):
    """Issue 26: ``kill -9`` of the supervising parent ends its child too (``PR_SET_PDEATHSIG``
    and the pipe watch): a stepping child stops at its next communication point and writes its
    files, a hung one writes the journal's rows and ends ``INTERRUPT_GRACE`` s later."""
    from cosim.run.supervisor import INTERRUPT_GRACE

    folder = _scenario(tmp_path, faulty, fault, fault_time=3.0 if fault == 4 else 0.0, stop=1000.0,
                       step=0.5 if fault == 4 else 0.1, delay=0.01)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv))
    _wait_for_journal_rows(tmp_path / "out.csv.journal", 7, proc)
    child, = _children(proc.pid)
    proc.kill()
    proc.wait(timeout=10)
    deadline = time.monotonic() + INTERRUPT_GRACE + 5.0
    while not _gone(child):
        assert time.monotonic() < deadline, "the child outlived its parent"
        time.sleep(0.1)
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted"
    res = read(csv)
    assert len(res) == (status_rows or round(meta["last_time"] / 0.1) + 1) > 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_running_out_of_memory_is_one_message_naming_the_result(tmp_path, faulty):
    """Issue 26: the address space exhausted mid-run (the FMU limits it at t = 1 as ``ulimit -v``
    would; the master's in-memory copy of the samples then outgrows it): one message saying
    memory ran out and naming the result file, exit 1, every recorded row in the CSV."""
    import re

    folder = _scenario(tmp_path, faulty, 6, fault_time=1.0, stop=1e6, step=0.1)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "-o", str(csv))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1 and "Traceback" not in err and "Error" not in err, err
    found = re.fullmatch(rf"cosim: the run failed \(out_of_memory\): {re.escape(str(csv))}: the process ran out of memory \(its "
                         r"address space: see ulimit -v\) at t = (\S+); the (\d+) rows recorded before are "
                         r"kept\.\n", err)
    assert found, err
    res = read(csv)
    assert len(res) == int(found.group(2)) > 10 and res["time"][-1] == pytest.approx(float(found.group(1)))
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "failed" and "ran out of memory" in meta["message"]
    assert not csv.with_name("out.csv.journal").exists()
