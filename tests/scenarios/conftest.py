"""Fixtures of the master tests of tests/scenarios (small_disk: test_outputs.py, test_disk_full.py)."""
import subprocess

import pytest


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MB tmpfs to fill (skipped where it cannot be mounted, e.g. without root)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs to fill: {done.stderr.decode().strip()}")
    yield mount
    subprocess.run(["umount", str(mount)], check=True)
