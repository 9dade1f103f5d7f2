"""The tests of tests/cosim/sweep/test_cluster_security.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim.cli import main

pytest.importorskip("distributed")
pytest.importorskip("cryptography")


ROOT = Path(__file__).resolve().parents[3]


DASK = str(Path(sys.executable).with_name("dask"))


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
                            "README's TLS recipe)."]
    else:
        assert warnings == []
    assert os.path.isfile(tmp_path / "out" / "sweep.parquet")


def _readme_tls_recipe() -> str:
    """The README's bash block that starts a ``dask scheduler``."""
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    [block] = [b for b in blocks if "dask scheduler" in b]
    return block


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


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


#: a client of the recipe's scheduler without its certificate (Dask's configuration not set yet),
#: once the scheduler listens
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
