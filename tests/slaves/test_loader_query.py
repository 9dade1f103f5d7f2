"""Issue 29: the loader's query of a candidate Python keeps its time limit and never hangs.

The loader (greyfmu/loader/platform.h, run_query) runs the candidate in a child process and reads
its answer with a time limit (60 s; 2 s in the loader compiled here with -DQUERY_SECONDS=2).
tests/signal_host.c sends the host one SIGALRM, with a handler installed without SA_RESTART,
while the query waits: an interrupted poll is retried against the same deadline (before, the
EINTR fell through to a read that blocked until the candidate exited, 20 s here).  A candidate
printing more than the 1 MiB kept is read to the end and refused.
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from dropinhost import environment, unzip
from greyfmu.loader import LOADER_SOURCE, PLATFORMS

HOST_SOURCE = Path(__file__).resolve().parents[1] / "signal_host.c"
LIMIT_SECONDS = 2


@pytest.fixture(scope="module")
def compiler() -> str:
    found = shutil.which("cc") or shutil.which("gcc")
    if found is None:
        pytest.skip("no C compiler (cc or gcc) on PATH to build tests/signal_host.c")
    return found


@pytest.fixture(scope="module")
def signal_host(compiler, tmp_path_factory) -> Path:
    host = tmp_path_factory.mktemp("signal") / "signal_host"
    subprocess.run([compiler, "-O1", "-Wall", "-Wextra", "-Werror", "-o", str(host), str(HOST_SOURCE), "-ldl"],
                   check=True)
    return host


@pytest.fixture
def quick_pid(compiler, built_fmus, tmp_path):
    """PID extracted, its linux64 loader rebuilt with a 2 s query limit."""
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    linux = PLATFORMS[0]
    subprocess.run([compiler, *linux.flags, f"-DQUERY_SECONDS={LIMIT_SECONDS}", "-Wall", "-Wextra", "-Werror", "-o",
                    str(fmu.folder / "binaries" / "linux64" / f"{fmu.identifier}.so"), str(LOADER_SOURCE),
                    *linux.libraries], check=True)
    return fmu


def candidate(folder: Path, body: str) -> Path:
    """A shell script standing for a candidate Python (GREYFMU_PYTHON)."""
    script = folder / "candidate"
    script.write_text(f"#!/bin/sh\n{body}\n")
    script.chmod(0o755)
    return script


def instantiate(host: Path, fmu, python: Path, signal_ms: int) -> tuple[float, list[str], str]:
    completed = subprocess.run([str(host), str(fmu.folder), fmu.identifier, fmu.guid, str(signal_ms)],
                               capture_output=True, text=True, timeout=120, env=environment(GREYFMU_PYTHON=str(python)))
    assert completed.returncode == 0 and completed.stdout.endswith("done\n"), completed.stdout + completed.stderr
    lines = completed.stdout.splitlines()
    result = next(line for line in lines if line.startswith("result ")).split()
    assert result[1] == "null", completed.stdout
    return float(result[2]), [line for line in lines if line.startswith("log ")], completed.stdout


def test_a_signal_during_the_query_keeps_the_time_limit(signal_host, quick_pid, tmp_path):
    silent = candidate(tmp_path, "exec sleep 20")
    seconds, logs, stdout = instantiate(signal_host, quick_pid, silent, signal_ms=300)
    assert "signals 1" in stdout
    assert len(logs) == 1 and f"{silent} did not answer within {LIMIT_SECONDS} s" in logs[0], logs
    assert LIMIT_SECONDS <= seconds < LIMIT_SECONDS + 5, seconds


def test_a_candidate_printing_more_than_a_mebibyte_is_read_to_the_end_and_refused(signal_host, quick_pid, tmp_path):
    chatty = candidate(tmp_path, "head -c 3145728 /dev/zero | tr '\\0' x")
    seconds, logs, _ = instantiate(signal_host, quick_pid, chatty, signal_ms=0)
    assert len(logs) == 1 and f"{chatty} did not run the check" in logs[0], logs
    assert seconds < LIMIT_SECONDS, seconds  # it ended by itself, not by the time limit
