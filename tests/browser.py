"""Headless Chromium for the tests of HTML pages (Debian's ``chromium``; .ci/run installs it)."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: the skip reason of a test that needs it
MISSING = "chromium is not installed (.ci/run installs Debian's chromium)"


def chromium(*args: str, tmp: Path) -> subprocess.CompletedProcess:
    """Run Chromium headless with its profile in ``tmp``."""
    profile = tmp / "profile"
    profile.mkdir(exist_ok=True)
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args], capture_output=True,
                          text=True, timeout=120)
