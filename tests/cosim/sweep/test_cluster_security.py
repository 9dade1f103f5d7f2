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
