"""`cosim sweep --scheduler ADDRESS` on a real Dask cluster: a ``dask scheduler`` and ``dask
worker`` processes started here, one worker in its own mount namespace where the project's
``ssp/`` and ``build/``, the sweep's output folder and its own temporary folder are empty tmpfs
mounts (what a machine with only greyfmu installed sees), and a worker killed in the middle of a sweep.
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.sweep import read_table, sweep

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[3]
DASK = str(Path(sys.executable).with_name("dask"))
SCENARIO = "ssp/pid_fopdt"
METRIC = "plant.y:setpoint.y"


def _wait_for(condition, what: str, timeout: float = 120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.2)
    raise TimeoutError(f"waited {timeout:.0f} s for {what}")


class Cluster:
    """A scheduler and workers as separate processes, stopped by `close`."""

    def __init__(self, folder: Path):
        self.folder = folder
        file = folder / "scheduler.json"
        self.processes: dict[str, subprocess.Popen] = {}
        self.scheduler = subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", "0",
                                           "--no-dashboard", "--scheduler-file", str(file)],
                                          stdout=subprocess.DEVNULL, stderr=(folder / "scheduler.log").open("w"))
        self.address = _wait_for(lambda: file.is_file() and json.loads(file.read_text() or "{}").get("address"),
                                 "the Dask scheduler")

    def worker(self, name: str, prefix: list[str] = (), env: dict[str, str] | None = None) -> None:
        command = [*prefix, DASK, "worker", self.address, "--name", name, "--nthreads", "1",
                   "--no-nanny", "--no-dashboard"]
        self.processes[name] = subprocess.Popen(command, stdout=subprocess.DEVNULL, env=env,
                                                stderr=(self.folder / f"{name}.log").open("w"))

    def client(self, workers: int):
        client = distributed.Client(self.address, timeout=30)
        client.wait_for_workers(workers, timeout=120)
        return client

    def kill(self, name: str) -> None:
        self.processes[name].send_signal(signal.SIGKILL)
        self.processes[name].wait()

    def close(self) -> None:
        for p in [*self.processes.values(), self.scheduler]:
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.close()


def _isolated(hidden: list[Path]) -> list[str]:
    """A command prefix running the rest in a new mount namespace with ``hidden`` as empty tmpfs."""
    mounts = " && ".join(f"mount -t tmpfs tmpfs '{p}'" for p in hidden)
    return ["unshare", "--mount", "--propagation", "private", "sh", "-c", f'{mounts} && exec "$@"', "isolated"]


def _unshare_works() -> str | None:
    probe = subprocess.run(_isolated([Path("/mnt")]) + ["true"], capture_output=True, text=True)
    return None if probe.returncode == 0 else (probe.stderr.strip() or f"exit status {probe.returncode}")


def _same_rows(remote: list[dict], local) -> None:
    assert [r["run_id"] for r in remote] == [r["run_id"] for r in local.rows]
    for a, b in zip(remote, local.rows):
        assert a["status"] == b["status"] == "completed", a["message"]
        for key in [c for c in local.columns if c.startswith(METRIC.split(":")[0] + ":")]:
            assert (math.isnan(a[key]) and math.isnan(b[key])) or abs(a[key] - b[key]) <= 1e-12, key


@pytest.mark.slow   # 28 s on the shared 2-core machine (build/test-durations.json)
def test_a_worker_that_sees_no_scenario_and_no_output_folder_runs_the_sweep(cluster, tmp_path):
    reason = _unshare_works()
    if reason is not None:
        pytest.skip(f"unshare --mount is not permitted here: {reason}")
    sets = {"plant.K": ["0.15", "0.2"], "controller.Kc": ["6", "8"]}
    out = tmp_path / "cluster_out"
    out.mkdir()
    local = sweep(SCENARIO, sets, metrics=[METRIC], output=tmp_path / "local", executor="serial")
    # the worker's temporary folder is a tmpfs of its own too (not all of /tmp: the checkout and
    # its virtual environment may live there, as in a CI clone)
    worker_tmp = tmp_path / "worker_tmp"
    worker_tmp.mkdir()
    cluster.worker("isolated", _isolated([ROOT / "ssp", ROOT / "build", out, worker_tmp]),
                   env={**os.environ, "TMPDIR": str(worker_tmp)})
    with cluster.client(1) as client:
        # what the worker sees: neither the scenario, nor the built FMUs, nor the output folder
        seen = client.run(lambda: [os.path.exists(ROOT / SCENARIO / "SystemStructure.ssd"),
                                   any((ROOT / "build").iterdir()), out.is_dir() and any(out.iterdir())])
        assert list(seen.values()) == [[False, False, False]]
        # the command of the issue, reaching the scheduler by its address
        set_args = [a for name, values in sets.items() for a in ("--set", f"{name}={','.join(values)}")]
        assert main(["sweep", SCENARIO, *set_args, "--metrics", METRIC, "--scheduler", cluster.address,
                     "--output", str(out), "--quiet"]) == 0
        cached = client.run(lambda: [(Path(tempfile.gettempdir()) / "cosim-sweep").exists(),
                                     any((ROOT / "build").iterdir())])
    remote = read_table(out / "sweep.parquet")
    _same_rows(remote, local)
    folders, built = list(cached.values())[0]
    assert not folders and not built     # its unpacked copy removed when the sweep ended; no FMU built there
    for row in remote:                                   # result files written by the client, as today
        for suffix in (".csv", ".json", ".ssv"):
            assert (out / "runs" / f"{row['run_id']}{suffix}").is_file()
        assert json.loads((out / "runs" / f"{row['run_id']}.json").read_text())["status"] == "completed"


@pytest.mark.slow   # 117 s on the shared 2-core machine (build/test-durations.json)
def test_a_worker_killed_during_a_sweep_costs_only_a_retry_of_its_runs(cluster, tmp_path):
    sets = {"plant.K": ["0.1", "0.15", "0.2", "0.25"], "controller.Kc": ["6", "8"]}
    stop = 3000.0           # about a second a run: the kill lands while both workers are busy
    local = sweep(SCENARIO, sets, metrics=[METRIC], stop_time=stop, output=tmp_path / "local", executor="serial")
    cluster.worker("a")
    cluster.worker("b")
    out = tmp_path / "cluster_out"
    with cluster.client(2) as client:
        outcome: dict = {}
        thread = threading.Thread(target=lambda: outcome.update(
            result=sweep(SCENARIO, sets, metrics=[METRIC], stop_time=stop, output=out, executor=client)))
        thread.start()
        _wait_for(lambda: (out / "sweep.parquet").is_file() and len(read_table(out / "sweep.parquet")) >= 1,
                  "the first finished run")
        names = {w["name"]: address for address, w in client.scheduler_info()["workers"].items()}
        busy = client.processing()[names["a"]]
        cluster.kill("a")
        finished_at_kill = len(read_table(out / "sweep.parquet"))
        thread.join(300)
    assert finished_at_kill < len(local.rows)
    assert busy                          # worker a had runs when it died
    _same_rows(outcome["result"].rows, local)
