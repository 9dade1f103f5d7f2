"""Issue 17: a sweep on the local process pool survives an FMU that kills its worker process
(a test FMU calling os.abort()), and Ctrl-C stops it at once with a complete table of the runs
that finished and no traceback."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pythonfmu.builder import FmuBuilder
from ssdgen import ssd_text, write_system

from cosim.sweep import read_table, sweep

HERE = Path(__file__).parent
COSIM = str(Path(sys.executable).with_name("cosim"))


@pytest.fixture(scope="module")
def aborting(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("aborting")
    fmu = Path(FmuBuilder.build_FMU(HERE / "fmus" / "Aborting.py", dest=folder, needsExecutionTool="false"))
    return write_system(folder / "system", {"Aborting.fmu": fmu},
                        ssd_text("crash", {"crash": ("Aborting.fmu", {"y": "output"})}, [], stop=1.0, step=0.01))


def test_an_fmu_that_aborts_its_process_fails_only_its_own_run(aborting, tmp_path):
    times = ["1e9", "0.5", "2e9", "3e9", "4e9"]
    result = sweep(aborting, {"crash.abort_time": times}, output=tmp_path, executor="process", workers=2)
    by_time = {r["crash.abort_time"]: r for r in result.rows}
    assert len(by_time) == 5
    assert by_time[0.5]["status"] == "failed" and by_time[0.5]["error"] == "worker_lost"
    assert "the worker process died during this run, and again when it was rerun alone" in by_time[0.5]["message"]
    assert all(by_time[t]["status"] == "completed" for t in (1e9, 2e9, 3e9, 4e9))
    assert len(read_table(tmp_path / "sweep.parquet")) == 5


@pytest.mark.slow   # 22 s on the shared 2-core machine (build/test-durations.json)
def test_ctrl_c_stops_the_sweep_at_once_and_keeps_the_finished_runs(aborting, tmp_path):
    out = tmp_path / "out"
    # 8 runs of some seconds each on 2 processes (2.4 million steps: the compiled kernel ran 120 000 in
    # 0.7 s): Ctrl-C lands after the first has finished
    command = [COSIM, "sweep", str(aborting), "--set", "crash.abort_time=1e9,2e9,3e9,4e9,5e9,6e9,7e9,8e9",
               "--stop", "24000", "--workers", "2", "--output", str(out), "--quiet"]
    # as a terminal's foreground job: SIGINT at its default disposition, even if this process
    # inherited it ignored (a shell's background job), which a started Python would keep
    default_sigint = [sys.executable, "-c", "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
                      "os.execv(sys.argv[1], sys.argv[1:])"]
    process = subprocess.Popen(default_sigint + command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    end = time.monotonic() + 300
    while not ((out / "sweep.parquet").is_file() and read_table(out / "sweep.parquet")):
        assert process.poll() is None and time.monotonic() < end, process.communicate()
        time.sleep(0.1)
    interrupted = time.monotonic()
    os.killpg(process.pid, signal.SIGINT)     # what Ctrl-C in a terminal sends: the whole process group
    out_text, err = process.communicate(timeout=60)
    stopped_after = time.monotonic() - interrupted
    rows = read_table(out / "sweep.parquet")
    assert process.returncode == 130, (out_text, err, f"{stopped_after:.2f} s after SIGINT", len(rows))
    assert "Traceback" not in err, err
    assert f"sweep interrupted; {len(rows)} finished runs are in" in err
    assert 1 <= len(rows) < 8 and all(r["status"] == "completed" for r in rows)
    assert len(open(out / "sweep.csv").read().splitlines()) == len(rows) + 1
    # a run lasts several seconds: stopping at once means well before the running ones could end
    print(f"stopped {stopped_after:.2f} s after SIGINT; runs took {[round(r['wall_time'], 2) for r in rows]} s")
    assert stopped_after < min(r["wall_time"] for r in rows), (stopped_after, [r["wall_time"] for r in rows])


def test_a_run_that_kills_every_dask_worker_it_lands_on_is_a_failed_row(aborting, tmp_path):
    # the scheduler reruns a run whose worker died on another worker (the nannies restart them)
    # until it has killed distributed.scheduler.allowed-failures + 1 of them: then Dask's
    # KilledWorker.  The runs beside it on a dying worker may end so too: each is tried once more
    # alone, where the innocent ones complete and the culprit is a failed row with its message.
    pytest.importorskip("distributed")
    times = ["1e9", "0.5", "2e9"]
    result = sweep(aborting, {"crash.abort_time": times}, output=tmp_path, executor="local:2")
    by_time = {r["crash.abort_time"]: r for r in result.rows}
    assert by_time[1e9]["status"] == by_time[2e9]["status"] == "completed"
    assert by_time[0.5]["status"] == "failed" and by_time[0.5]["error"] == "worker_lost"
    assert by_time[0.5]["message"].startswith("KilledWorker:") and "workers died" in by_time[0.5]["message"]
    assert "Rerun alone, it killed its workers again." in by_time[0.5]["message"]
    assert len(read_table(tmp_path / "sweep.parquet")) == 3
