"""The FMU's fix hint when the target Python lacks numpy/scipy (issue 45): on Debian's own python3
(externally managed, PEP 668) pip refuses to install, so the hint names Debian's packages or a
virtual environment, never ``python3 -m pip install``.  Runs the FMU's resources/greyfmu_target.py
as the loader does (``--query``, in a child process) under /usr/bin/python3; about 0.3 s."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

import greyfmu.loader

DEBIAN_PYTHON = Path("/usr/bin/python3")
TARGET = Path(greyfmu.loader.__file__).parent / "greyfmu_target.py"


def problem(tmp_path: Path, requirements: str) -> str:
    shutil.copy(TARGET, tmp_path / "greyfmu_target.py")
    (tmp_path / "greyfmu_requirements.txt").write_text(requirements)
    out = subprocess.run([str(DEBIAN_PYTHON), str(tmp_path / "greyfmu_target.py"), "--query"], capture_output=True,
                         check=True).stdout.decode()
    return next(line for line in out.splitlines() if line.startswith("greyfmu-problem=")).partition("=")[2]


@pytest.fixture
def externally_managed() -> None:
    script = "import sys, sysconfig, os; print(os.path.isfile(os.path.join(sysconfig.get_path('stdlib'), " \
             "'EXTERNALLY-MANAGED')), end='')"
    if not DEBIAN_PYTHON.is_file():
        pytest.skip("no /usr/bin/python3")
    managed = subprocess.run([str(DEBIAN_PYTHON), "-c", script], capture_output=True, text=True).stdout
    if managed != "True":
        pytest.skip("/usr/bin/python3 is not externally managed (not Debian 12 or later)")


def test_debians_python_gets_apt_or_a_venv_not_pip(tmp_path, externally_managed):
    text = problem(tmp_path, "greyfmu_no_such_module_a\n")
    assert "-m pip install greyfmu_no_such_module_a`" not in text.split("venv")[0], text
    assert "externally managed" in text and "-m venv" in text and "GREYFMU_PYTHON=" in text
    (tmp_path / "deb").mkdir()
    text = problem(tmp_path / "deb", "numpy\nscipy\n")
    if text:   # numpy and scipy missing from Debian's python3 (CI's machine): the Debian packages first
        assert "sudo apt-get install python3-numpy python3-scipy" in text, text
        assert not text.startswith(f"{DEBIAN_PYTHON} cannot import numpy (ModuleNotFoundError: No module named "
                                   "'numpy'), scipy (ModuleNotFoundError: No module named 'scipy'): install with")
