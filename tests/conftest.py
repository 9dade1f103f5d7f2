"""Shared fixtures, and the record of the suite's time: every run writes each test's time (set-up,
call and tear-down) and each file's to build/test-durations.json (`pytest_sessionfinish`), and the
slowest files in its summary; ``@pytest.mark.slow`` marks a test of more than about 20 s."""

import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
from hypothesis import settings

# Hypothesis profiles (tests/scenarios/test_fuzz.py scales its example counts by max_examples: 500 fuzz
# examples in all by default, 10 000 in the nightly run).  Select the nightly size with
# COSIM_FUZZ=nightly or `pytest --hypothesis-profile nightly`; every example must end in 5 s.
settings.register_profile("default", max_examples=100, deadline=5000)
settings.register_profile("nightly", max_examples=2000, deadline=5000)
#: the tests' FMU cache (cosim.read.fmucache): one folder per session, shared with the processes
#: the tests start, not the user's ~/.cache
_FMU_CACHE = tempfile.TemporaryDirectory(prefix="cosim-test-fmu-cache-")
os.environ.setdefault("COSIM_FMU_CACHE", _FMU_CACHE.name)

if "COSIM_FUZZ" in os.environ:
    settings.load_profile(os.environ["COSIM_FUZZ"])


@pytest.fixture(scope="session")
def debian_python() -> Path:
    """The python of a virtual environment made from Debian's /usr/bin/python3 (static libpython),
    the project installed (tests/pythons.py, cached in ~/.cache/greyfmu/pythons); skipped where there is none."""
    from pythons import Unavailable, debian_venv

    try:
        return debian_venv()
    except Unavailable as why:
        pytest.skip(str(why))


@pytest.fixture(scope="session")
def built_fmus() -> dict[str, Path]:
    """All FMUs of fmus/, built once per session into build/fmus (kept if up to date); greyfmu.build
    (which needs pythonfmu) is imported here so that tests/cosim collects and runs without it."""
    from greyfmu.build import build_fmus

    return {path.stem: path for path in build_fmus()}


@pytest.fixture(scope="session")
def twin_fmus(tmp_path_factory) -> dict[str, Path]:
    """The C twins of our Step, Gain and FirstOrderFilter FMUs (tests/twin_fmus.py), by name: the
    master's tests that need "some" source, gain or lag run without pythonfmu."""
    from twin_fmus import build_twins

    return {Path(name).stem: path for name, path in build_twins(tmp_path_factory.mktemp("twins")).items()}


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MB tmpfs to fill (skipped where it cannot be mounted, e.g. without root):
    tests/cosim/test_disk_full.py, tests/scenarios/test_outputs.py."""
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs to fill: {done.stderr.decode().strip()}")
    yield mount
    subprocess.run(["umount", str(mount)], check=True)


@pytest.fixture
def cosim_references_dir() -> Path:
    """Our own regression references stay in one folder, tests/references (the plugin's default
    is a folder beside each test file, for the users' tests)."""
    return Path(__file__).resolve().parent / "references"


@pytest.fixture(autouse=True, scope="session")
def _repository_root() -> None:
    """Scenario paths in the tests (ssp/...) are relative to the repository root."""
    os.chdir(Path(__file__).resolve().parents[1])


@pytest.fixture(autouse=True, scope="session")
def _installed_pythonfmu3_first() -> None:
    """The installed pythonfmu3 imported before any test runs an FMI 3.0 FMU in this process: a
    pythonfmu3 FMU puts its resources/ on sys.path and its slave imports the FMU's own copy of
    pythonfmu3 (no builder binaries) when none is imported yet, and a later build here then made
    FMUs without binaries (greyfmu.build now refuses that).  Which test runs first depends on the
    test worker (tests/run.sh runs pytest -n); without pythonfmu3 (tests/cosim) nothing to do."""
    try:
        import pythonfmu3.builder  # noqa: F401
    except ImportError:
        pass


@pytest.fixture(autouse=True, scope="session")
def _release_pythonfmu_state_before_fmpy_unloads() -> None:
    """Tests also run our FMUs through fmpy.simulate_fmu, which unloads each library when it
    is done: empty pythonfmu 0.7.0's static interpreter state first, as cosim does (see
    cosim.run.instances.pythonfmu_state.release_pythonfmu_state: otherwise the unload can corrupt the heap)."""
    from fmpy.fmi1 import _FMU

    from cosim.run.instances.pythonfmu_state import release_pythonfmu_state

    unload = _FMU.freeLibrary

    def free_library(self):
        release_pythonfmu_state(self.dll)
        unload(self)

    _FMU.freeLibrary = free_library
    yield
    _FMU.freeLibrary = unload


#: each test's time in this session (set-up, call and tear-down), by node id
_DURATIONS: dict[str, float] = {}
_STARTED = time.monotonic()


def pytest_runtest_logreport(report) -> None:
    _DURATIONS[report.nodeid] = _DURATIONS.get(report.nodeid, 0.0) + report.duration


def _by_file() -> dict[str, float]:
    files: dict[str, float] = {}
    for nodeid, seconds in _DURATIONS.items():
        file = nodeid.split("::", 1)[0]
        files[file] = files.get(file, 0.0) + seconds
    return dict(sorted(files.items(), key=lambda kv: -kv[1]))


def pytest_sessionfinish(session, exitstatus) -> None:
    """build/test-durations.json: the wall time of the session, the time of each file and test,
    slowest first (written by the process that reports: with pytest-xdist, the controller)."""
    if hasattr(session.config, "workerinput") or not _DURATIONS:
        return
    path = Path(session.config.rootpath) / "build" / "test-durations.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    tests = dict(sorted(_DURATIONS.items(), key=lambda kv: -kv[1]))
    path.write_text(json.dumps({"wall_seconds": round(time.monotonic() - _STARTED, 3),
                                "test_seconds": round(sum(tests.values()), 3), "tests": len(tests),
                                "files": {f: round(s, 3) for f, s in _by_file().items()},
                                "slowest": {t: round(s, 3) for t, s in tests.items()}}, indent=1) + "\n")


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    if hasattr(config, "workerinput") or len(_DURATIONS) < 2:
        return
    files = list(_by_file().items())[:5]
    terminalreporter.write_line("test durations (build/test-durations.json): " + ", ".join(
        f"{Path(f).name} {s:.0f} s" for f, s in files) + f"; {sum(_DURATIONS.values()):.0f} s in all tests")
