"""What TLS costs a ``local:N`` sweep cluster at start: the cluster `cosim.sweep.cluster.local_cluster`
starts (TLS, a key and certificate made per sweep) against the same LocalCluster on plain TCP
(what ``local:N`` was before issue 26), each from nothing to a client that sees its N workers,
and its close.

    python benchmarks/bench_cluster_start.py [--workers 2] [--repeats 5]

The two kinds alternate, ``--repeats`` times each; prints every time and the medians.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


@contextmanager
def plain_cluster(workers: int):
    """The LocalCluster of ``local:N`` before TLS."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        yield cluster
    finally:
        cluster.close()


def timed(start, workers: int) -> tuple[float, float]:
    """Seconds to a client seeing ``workers`` workers, and seconds to close it all."""
    from distributed import Client

    began = time.perf_counter()
    with start(workers) as cluster:
        with Client(cluster, security=cluster.security) as client:
            client.wait_for_workers(workers)
            up = time.perf_counter() - began
        closing = time.perf_counter()
    return up, time.perf_counter() - closing


def main() -> None:
    from cosim.sweep.cluster import local_cluster

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    times: dict[str, list[tuple[float, float]]] = {"tcp": [], "tls": []}
    for _ in range(args.repeats):
        for name, start in (("tcp", plain_cluster), ("tls", local_cluster)):
            times[name].append(timed(start, args.workers))
            print(f"{name}: up {times[name][-1][0]:.3f} s, closed in {times[name][-1][1]:.3f} s", flush=True)
    for name, values in times.items():
        print(f"median {name} ({args.workers} workers): up {statistics.median(v[0] for v in values):.3f} s, "
              f"close {statistics.median(v[1] for v in values):.3f} s")


if __name__ == "__main__":
    main()
