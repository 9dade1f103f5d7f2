"""Issue 29: fmi2Instantiate runs on a host's worker thread with a small stack.

tests/stack_host.c (compiled here with the system compiler) calls the FMU's fmi2Instantiate,
one step and fmi2FreeInstance on threads with a 64 KiB stack above a guard page, and reports
the bytes of each stack written.  The loader keeps its buffers on the heap
(greyfmu/loader/fmi2_loader.c): measured on PID, 46 KiB for the first call (Python started in
the host, numpy imported) and 28 KiB for a later one, Python's and pythonfmu's frames included;
with the buffers on the stack (82 KB frame of fmi2Instantiate) the same calls used 129 and
111 KiB, and a 64 KiB thread died of SIGSEGV.
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from dropinhost import environment, unzip

HOST_SOURCE = Path(__file__).resolve().parents[1] / "stack_host.c"
STACK_KIB = 64


@pytest.fixture(scope="module")
def stack_host(tmp_path_factory) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (cc or gcc) on PATH to build tests/stack_host.c")
    host = tmp_path_factory.mktemp("stack") / "stack_host"
    subprocess.run([compiler, "-O1", "-Wall", "-Wextra", "-Werror", "-o", str(host), str(HOST_SOURCE), "-ldl",
                    "-lpthread"], check=True)
    return host


def test_instantiate_on_a_64_kib_thread_starts_python_and_steps(stack_host, built_fmus, tmp_path):
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    completed = subprocess.run([str(stack_host), str(fmu.folder), fmu.identifier, fmu.guid, str(STACK_KIB),
                                str(STACK_KIB), str(STACK_KIB)], capture_output=True, text=True, timeout=300,
                               env=environment())
    assert completed.returncode == 0, f"the host crashed ({completed.returncode}):\n{completed.stdout[-3000:]}\n" \
                                      f"{completed.stderr[-3000:]}"
    calls = [line.split() for line in completed.stdout.splitlines() if line.startswith("call ")]
    assert [(kib, status) for _, _, kib, status, _ in calls] == [(str(STACK_KIB), "instance")] * 3, completed.stdout
    used = [int(call[4]) for call in calls]
    assert all(0 < bytes_used < STACK_KIB * 1024 for bytes_used in used), used  # the stack was measured
