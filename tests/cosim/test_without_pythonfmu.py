"""tests/cosim runs without pythonfmu (tests/cosim/conftest.py): each of its tests, and each process a
test starts, finds pythonfmu, pythonfmu3 and greyfmu.build unimportable, as on a machine with only
the master installed; a test marked ``pythonfmu`` finds them."""
from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

BLOCKED = ("pythonfmu", "pythonfmu3", "greyfmu.build", "pythonfmu.builder")


@pytest.mark.parametrize("module", BLOCKED)
def test_a_test_here_cannot_import_pythonfmu(module):
    with pytest.raises(ImportError, match="is blocked by tests/blocker.py"):
        importlib.import_module(module)


def test_nor_can_a_process_it_starts():
    done = subprocess.run([sys.executable, "-c", "import pythonfmu3"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "pythonfmu3 is blocked by tests/blocker.py" in done.stderr, done.stderr


@pytest.mark.pythonfmu
def test_a_marked_test_can():
    for module in BLOCKED:
        importlib.import_module(module)
