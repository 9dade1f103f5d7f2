"""The tests of tests/cosim/test_output_safety.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.errors import SetupError
from cosim.record.results import read
from runhelpers import refused as _refused
from cosim.safeio import lock_output, lock_path, partial_path


SCENARIO = Path("ssp/pid_fopdt").resolve()


STOP = "2"   # 20 steps of 0.1 s


@pytest.fixture
def scenario(tmp_path) -> Path:
    return Path(shutil.copytree(SCENARIO, tmp_path / "pid_fopdt"))


@pytest.fixture
def cwd(tmp_path, monkeypatch) -> Path:
    """A working folder two levels down, so ``../../x`` would land in tmp_path."""
    here = tmp_path / "a" / "b"
    here.mkdir(parents=True)
    monkeypatch.chdir(here)
    return here




def _named(scenario: Path, name: str) -> Path:
    ssd = scenario / "SystemStructure.ssd"
    text = ssd.read_text()
    assert 'name="pid_fopdt"' in text
    ssd.write_text(text.replace('name="pid_fopdt"', f'name="{name}"', 1))
    return scenario


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize("name", ["../../x", "ABSOLUTE"])
def test_an_ssd_name_that_is_a_path_never_places_the_default_result(scenario, cwd, capsys, tmp_path, name):
    name = str(tmp_path / "abs" / "x") if name == "ABSOLUTE" else name   # /abs/x, kept in tmp_path
    target = Path(name).with_suffix(".csv")
    target = target if target.is_absolute() else (cwd / "results" / target).resolve()
    before = _files(tmp_path)
    err = _refused(capsys, "run", str(_named(scenario, name)), "--stop", STOP, "-q")
    assert f"SystemStructure.ssd, ssd:SystemStructureDescription name: the system name {name!r} cannot be a " \
           "file name: it holds '/'" in err and "--output" in err
    assert _files(tmp_path) == before and not target.exists()
    assert main(["run", str(scenario), "--stop", STOP, "-q", "-o", "given.csv"]) == 0   # -o needs no default name
    assert (cwd / "given.csv").is_file()


def test_a_parameter_set_name_that_is_no_portable_file_name_is_refused(scenario, cwd, capsys):
    ssv = scenario / "case:1.ssv"
    shutil.copy(scenario / "pi_only.ssv", ssv)
    err = _refused(capsys, "run", str(scenario), "--stop", STOP, "-q", "--param-set", str(ssv))
    assert f"{ssv}, --param-set: the parameter set name 'case:1' cannot be a file name: it holds ':'" in err
    assert not (cwd / "results").exists()


def test_the_sweep_s_default_folder_is_named_after_the_scenario_folder_itself(scenario, cwd, capsys):
    """``cosim sweep S/sub/..`` was results/.._sweep; the name is the resolved folder's."""
    (scenario / "sub").mkdir()
    assert main(["sweep", str(scenario / "sub" / ".."), "--set", "plant.T=15", "--stop", STOP, "-q",
                 "--workers", "1"]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (cwd / "results").iterdir()) == ["pid_fopdt_sweep"]
    assert (cwd / "results" / "pid_fopdt_sweep" / "sweep.csv").is_file()


def test_a_second_writer_of_an_output_is_refused_naming_the_holder(scenario, tmp_path, capsys):
    out = tmp_path / "same.csv"
    with lock_output(out):
        assert lock_path(out).read_text() == f"{os.getpid()}\n"
        err = _refused(capsys, "run", str(scenario), "--stop", STOP, "-q", "-o", str(out))
        assert f"{out} is being written by process {os.getpid()} (it holds the lock {lock_path(out)})" in err
        assert not out.exists()
    assert not lock_path(out).exists()   # released and removed
    assert main(["run", str(scenario), "--stop", STOP, "-q", "-o", str(out)]) == 0
    assert not lock_path(out).exists() and not partial_path(out).exists()


def test_the_python_api_takes_the_same_lock(scenario, tmp_path):
    from cosim.run.simulation import simulate

    out = tmp_path / "api.csv"
    with lock_output(out), pytest.raises(SetupError) as e:
        simulate(scenario, stop_time=1.0, output=out)
    assert f"output: {out} is being written by process {os.getpid()}" in str(e.value) and not out.exists()
    assert len(simulate(scenario, stop_time=1.0, output=out)) == 11 and len(read(out)) == 11
    assert not lock_path(out).exists() and not partial_path(out).exists()


def test_a_run_killed_mid_way_leaves_the_earlier_result_and_blocks_no_one(scenario, tmp_path, capsys):
    """Two real `cosim run` processes on one output: the second is refused naming the first's pid;
    the earlier good CSV stays whole while the first writes and after it is killed (SIGKILL to
    it and its supervised child); its stale lock blocks no later run."""
    out = tmp_path / "same.csv"
    assert main(["run", str(scenario), "--stop", STOP, "-q", "-o", str(out)]) == 0
    good = out.read_bytes(), out.with_suffix(".json").read_bytes()
    first = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(scenario), "--stop", "1e7", "-q",
                              "-o", str(out)], start_new_session=True, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not (partial_path(out).exists() and partial_path(out).stat().st_size > 1000):
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        err = _refused(capsys, "run", str(scenario), "--stop", STOP, "-q", "-o", str(out))
        assert f"{out} is being written by process {first.pid} " in err
        assert (out.read_bytes(), out.with_suffix(".json").read_bytes()) == good   # a reader sees the old one
    finally:
        os.killpg(first.pid, signal.SIGKILL)
        first.wait()
    assert (out.read_bytes(), out.with_suffix(".json").read_bytes()) == good
    assert lock_path(out).exists()   # stale: its holders are dead (the supervised child ends a moment later)
    deadline = time.monotonic() + 30
    while not _free(out):
        assert time.monotonic() < deadline
        time.sleep(0.05)
    assert main(["run", str(scenario), "--stop", "1", "-q", "-o", str(out)]) == 0
    assert len(read(out)) == 11 and not lock_path(out).exists() and not partial_path(out).exists()


def _free(out: Path) -> bool:
    try:
        lock_output(out).release()
    except SetupError:
        return False
    return True


def _sweep_args(scenario: Path, out: Path) -> list[str]:
    return ["sweep", str(scenario), "--set", "plant.T=15", "--stop", STOP, "-q", "--workers", "1", "-o", str(out)]


def test_a_sweep_holds_its_tables_and_its_folder_is_its_own(scenario, tmp_path, capsys):
    out = tmp_path / "sw"
    with lock_output(out / "sweep.csv"):   # as a `cosim run -o sw/sweep.csv` in progress holds it
        err = _refused(capsys, *_sweep_args(scenario, out))
        assert f"{out / 'sweep.csv'} is being written by process {os.getpid()}" in err
    assert main(_sweep_args(scenario, out)) == 0, capsys.readouterr().err
    table = (out / "sweep.csv").read_bytes()
    assert not list(out.glob("*.lock")) and not list(out.rglob("*.part"))
    for target in (out / "sweep.csv", out / "other.csv", out / "runs" / "x.csv"):
        err = _refused(capsys, "run", str(scenario), "--stop", STOP, "-q", "-o", str(target))
        assert f"{target} is in the folder of a sweep ({out}, which holds sweep.csv)" in err
    assert (out / "sweep.csv").read_bytes() == table and not (out / "other.csv").exists()


def test_a_sweep_never_replaces_a_run_s_results_named_sweep(scenario, tmp_path, capsys):
    out = tmp_path / "mine"
    assert main(["run", str(scenario), "--stop", STOP, "-q", "-o", str(out / "sweep.csv")]) == 0
    result = (out / "sweep.csv").read_bytes()
    err = _refused(capsys, *_sweep_args(scenario, out))
    assert f"{out} holds a run's results named sweep.* ({out / 'sweep.json'} is its metadata)" in err
    assert (out / "sweep.csv").read_bytes() == result
