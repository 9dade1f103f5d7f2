"""Who may use a sweep's Dask cluster (issue 26).

A ``local:N`` cluster (started by the code `cosim sweep --scheduler local:N` runs) speaks only
TLS with a certificate made for the sweep: another process of this machine that connects to
its scheduler, a worker or a nanny, with plain TCP or with a certificate of its own, is refused
and runs nothing.  A scheduler given by address that is neither TLS nor on loopback gets one
warning line naming it.
"""
from __future__ import annotations

import asyncio
import sys
import tempfile
from pathlib import Path

import pytest

from cosim.sweep.cluster import is_open, local_cluster

distributed = pytest.importorskip("distributed")
pytest.importorskip("cryptography")

import cloudpickle  # noqa: E402 -- with Dask, as psutil
import psutil  # noqa: E402
from distributed.comm.utils import get_tcp_server_addresses  # noqa: E402
from distributed.protocol.pickle import dumps  # noqa: E402
import json
import os
import re
import shlex
import shutil
import socket
import subprocess
import time
from cosim.cli import main

# the functions the "foreign" clients send are pickled whole (the workers need not import this module)
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _touch(path: str) -> str:
    Path(path).touch()
    return "ran"


def _submit_as_foreigner(address: str, security, marker: Path) -> Exception | None:
    """What another process does: connect to the scheduler and have it run ``_touch(marker)``;
    the exception that stopped it, None if the task ran."""
    try:
        with distributed.Client(address, security=security, timeout=5) as client:
            client.submit(_touch, str(marker), pure=False).result(timeout=30)
    except Exception as e:  # noqa: BLE001 -- whatever refused it
        return e
    return None


def _run_on_as_foreigner(address: str, security, marker: Path) -> Exception | None:
    """The same straight at a worker or a nanny, bypassing the scheduler (their ``run`` handler)."""
    async def attempt():
        args = security.get_connection_args("client") if security is not None else {}
        async with distributed.rpc(address, connection_args=args, timeout=5) as remote:
            reply = await remote.run(function=dumps(_touch), args=dumps((str(marker),)), kwargs=dumps({}))
        assert reply["status"] == "OK", reply

    try:
        asyncio.run(attempt())
    except Exception as e:  # noqa: BLE001
        return e
    return None


def _plain(address: str) -> str:
    return "tcp://" + address.split("://", 1)[1]


def test_a_local_cluster_refuses_clients_without_the_sweeps_certificate(tmp_path, monkeypatch):
    # the cluster's processes and Dask's own temporary files in a folder of this test's own,
    # searched for the key afterwards
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", None)
    (tmp_path / "tmp").mkdir()
    foreign = distributed.Security.temporary()       # a certificate of another cluster
    with local_cluster(1) as cluster, distributed.Client(cluster, security=cluster.security) as own:
        own.wait_for_workers(1, timeout=60)
        workers = own.scheduler_info()["workers"]
        listeners = [cluster.scheduler_address, *workers, *(w["nanny"] for w in workers.values())]
        assert len(listeners) == 3
        scheduler = cluster.scheduler_address
        refusals = {
            "plain tcp client": _submit_as_foreigner(_plain(scheduler), None, tmp_path / "a"),
            "tls client without certificate": _submit_as_foreigner(scheduler, None, tmp_path / "b"),
            "tls client with another certificate": _submit_as_foreigner(scheduler, foreign, tmp_path / "c"),
        }
        for i, address in enumerate(listeners[1:]):
            refusals[f"plain rpc to {address}"] = _run_on_as_foreigner(_plain(address), None, tmp_path / f"d{i}")
            refusals[f"rpc to {address} with another certificate"] = _run_on_as_foreigner(
                address, foreign, tmp_path / f"e{i}")
        # the cluster was up and working meanwhile: the sweep's own client runs a task
        assert own.submit(_touch, str(tmp_path / "own"), pure=False).result(timeout=60) == "ran"
        assert {name: e for name, e in refusals.items() if e is None} == {}
        assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == ["own"]   # no foreign task ran
        assert isinstance(refusals["plain tcp client"], OSError)
        assert "TLS certificate does not match" in str(refusals["tls client with another certificate"])
        # the key only in memory and in the pipes to the worker processes
        key_line = cluster.security.tls_scheduler_key.splitlines()[1]
        children = psutil.Process().children(recursive=True)
        assert [p.pid for p in children if key_line in " ".join(p.cmdline()) + repr(p.environ())] == []
        assert [p for p in (tmp_path / "tmp").rglob("*") if p.is_file() and key_line in p.read_text("latin-1")] == []
        assert all(a.startswith("tls://127.0.0.1:") for a in listeners)


def test_two_local_clusters_at_once_serve_http_on_free_loopback_ports(recwarn):
    """The scheduler's HTTP server (health and metrics; no dashboard) listens on loopback on a
    port of its own: two sweeps of one machine do not fight over Dask's 8787 (the second one
    warned and the first one held it on every sweep)."""
    with local_cluster(1) as one, local_cluster(1) as two:
        bound = [sorted(get_tcp_server_addresses(c.scheduler.http_server)) for c in (one, two)]
    assert all(len(b) == 1 and b[0][0] == "127.0.0.1" for b in bound), bound
    assert bound[0][0][1] != bound[1][0][1] and 8787 not in (bound[0][0][1], bound[1][0][1]), bound
    assert [str(w.message) for w in recwarn if "already in use" in str(w.message)] == []


@pytest.mark.parametrize("address, open_", [
    ("tcp://192.0.2.7:8786", True),
    ("192.0.2.7:8786", True),                  # Dask's default scheme is tcp
    ("tcp://[2001:db8::1]:8786", True),
    ("ws://192.0.2.7:8786", True),
    ("tcp://0.0.0.0:8786", True),
    ("tcp://127.0.0.1:8786", False),
    ("tcp://127.8.9.10:8786", False),
    ("tcp://[::1]:8786", False),
    ("tcp://localhost:8786", False),
    ("tls://192.0.2.7:8786", False),           # authenticated by certificate
    ("tcp://no-such-host.invalid:8786", True),
])
def test_which_scheduler_addresses_are_open(address, open_):
    assert is_open(address) is open_


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


pytest.importorskip("distributed")


pytest.importorskip("cryptography")


ROOT = Path(__file__).resolve().parents[3]


DASK = str(Path(sys.executable).with_name("dask"))


@pytest.mark.pythonfmu
def test_a_tls_scheduler_without_a_certificate_in_dasks_configuration_is_a_setup_error(tmp_path, capsys):
    status = main(["sweep", "ssp/pid_fopdt", "--set", "controller.Kc=8", "--stop", "1",
                   "--scheduler", "tls://127.0.0.1:1", "--output", str(tmp_path), "--quiet"])
    assert status == 2
    err = capsys.readouterr().err
    assert "cosim: error: --scheduler: cannot talk TLS to the Dask scheduler" in err
    assert "DASK_DISTRIBUTED__COMM__TLS__CA_FILE" in err and "Traceback" not in err


def _outside_address() -> str | None:
    """An address of this machine other than loopback, None if it has none."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(("192.0.2.1", 9))   # no packet is sent: this only picks the outgoing interface
        address = probe.getsockname()[0]
    except OSError:
        return None
    finally:
        probe.close()
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def _scheduler(folder: Path, host: str) -> tuple[subprocess.Popen, str]:
    file = folder / "scheduler.json"
    with (folder / "scheduler.log").open("w") as log:
        process = subprocess.Popen([DASK, "scheduler", "--host", host, "--port", "0", "--no-dashboard",
                                    "--scheduler-file", str(file)], stdout=subprocess.DEVNULL, stderr=log)
    end = time.monotonic() + 60
    while time.monotonic() < end:
        if file.is_file() and json.loads(file.read_text() or "{}").get("address"):
            return process, json.loads(file.read_text())["address"]
        time.sleep(0.2)
    process.kill()
    raise TimeoutError("the Dask scheduler did not start")


@pytest.mark.pythonfmu
@pytest.mark.parametrize("where", ["outside", "loopback"])
def test_a_sweep_on_an_open_scheduler_warns_once_naming_it(tmp_path, capsys, where):
    host = _outside_address() if where == "outside" else "127.0.0.1"
    if host is None:
        pytest.skip("this machine has no address other than loopback")
    scheduler, address = _scheduler(tmp_path, host)
    with (tmp_path / "worker.log").open("w") as log:
        worker = subprocess.Popen([DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                                  stdout=subprocess.DEVNULL, stderr=log)
    try:
        status = main(["sweep", "ssp/pid_fopdt", "--set", "controller.Kc=8", "--stop", "1",
                       "--scheduler", address, "--output", str(tmp_path / "out"), "--quiet"])
    finally:
        for p in (worker, scheduler):
            p.terminate()
            p.wait(30)
    assert status == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    if where == "outside":
        assert warnings == [f"cosim: warning: the Dask scheduler {address} is neither TLS nor on loopback: "
                            "anyone who can reach it can run code on its workers, as their user (see the "
                            "TLS recipe in docs/sweeps.md)."]
    else:
        assert warnings == []
    assert os.path.isfile(tmp_path / "out" / "sweep.parquet")


def _readme_tls_recipe() -> str:
    """The bash block of docs/sweeps.md ("Whom a cluster obeys", once the README's) that starts a ``dask scheduler``."""
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "docs" / "sweeps.md").read_text(), flags=re.S)
    [block] = [b for b in blocks if "dask scheduler" in b]
    return block


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.pythonfmu
def test_the_readmes_tls_cluster_recipe_runs_a_sweep_and_refuses_others(tmp_path):
    if shutil.which("openssl") is None:
        pytest.skip("no openssl command")
    port = _free_port()
    recipe = _readme_tls_recipe().replace("8786", str(port)).replace("ssp/pid_fopdt", str(ROOT / "ssp/pid_fopdt"))
    foreign = f"{sys.executable} -c {shlex.quote(FOREIGN.format(port=port))}"
    # run as written, in a shell whose background jobs (scheduler, worker) are stopped at its end;
    # before the sweep's line, a client without the certificate tries to run something
    lines = recipe.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("cosim sweep"))
    script = "\n".join(["set -euo pipefail", "trap 'kill $(jobs -p) 2>/dev/null' EXIT", *lines[:at],
                        foreign, *lines[at:]])
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "refused: " in done.stdout and not (tmp_path / "foreign-ran").exists()
    assert "2 runs (2 ran now, 0 already done and skipped, 0 failed)" in done.stdout
    assert "cosim: warning" not in done.stderr   # a TLS scheduler is not an open one
    assert all((tmp_path / name).stat().st_mode & 0o077 == 0 for name in ("ca.key", "sweep.key"))


FOREIGN = """
import socket, time, distributed
deadline = time.monotonic() + 60
while socket.socket().connect_ex(("127.0.0.1", {port})) != 0 and time.monotonic() < deadline:
    time.sleep(0.2)
try:
    with distributed.Client("tcp://127.0.0.1:{port}", timeout=5) as c:
        c.submit(open, "foreign-ran", "w", pure=False).result()
    print("ran")
except OSError as e:
    print("refused:", type(e).__name__)
"""
