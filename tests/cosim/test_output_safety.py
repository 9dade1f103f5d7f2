"""Where results go and who writes them (issue 26, items 2 and 3).

Before: an SSD named ``../../x`` or ``/abs/x`` had `cosim run` write its CSV and JSON outside
``results/``, a worker's file named ``../../x`` was written outside the sweep's folder, a
regression ``reference="../../x"`` outside the references folder; two `cosim run -o same.csv`
both exited 0, one's results silently replacing the other's, a run killed mid-way had already
truncated the earlier result, and `cosim sweep -o FILE` was a NotADirectoryError traceback."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from cosim.errors import SetupError
from cosim.record.results import read
from runhelpers import refused as _refused
from cosim.safeio import file_name
import os
import signal
import subprocess
import sys
import time
from cosim.cli import main
from cosim.safeio import lock_output, lock_path, partial_path

SCENARIO = Path("ssp/pid_fopdt").resolve()
STOP = "2"   # 20 steps of 0.1 s


@pytest.fixture
def scenario(tmp_path) -> Path:
    return Path(shutil.copytree(SCENARIO, tmp_path / "pid_fopdt"))




def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file()}


# --------------------------------------------------------------------------- names are file names

@pytest.mark.parametrize("name", ["../../x", "/abs/x", "a/b", "a\\b", "..", ".", "", "a\0b", "a\nb", "C:x",
                                  "con", "NUL.csv", "com1", "Lpt9.txt", "a?b", "x" * 201])
def test_a_name_that_is_not_a_plain_file_name_is_refused(name):
    with pytest.raises(SetupError) as e:
        file_name(name, what="the system name", file="S.ssd", element="ssd:SystemStructureDescription name")
    assert str(e.value).startswith("S.ssd, ssd:SystemStructureDescription name: the system name")
    assert "cannot be a file name" in str(e.value)


def test_a_name_that_is_not_text_is_refused():
    with pytest.raises(SetupError, match="it is a bytes, not text"):
        file_name(b"x.csv", what="the file a worker returned")


@pytest.mark.parametrize("name", ["pid_fopdt", "..a", "a..b", "x.y.csv", "console", "Überschwinger", "x" * 200])
def test_plain_file_names_pass(name):
    assert file_name(name, what="the system name") == name


def _task(folder: Path):
    from cosim.sweep.dispatch import Task
    return Task("abc123", "S", (), (), 0.0, 1.0, 0.1, "jacobi", str(folder / "abc123.csv"), (), 1)


@pytest.mark.parametrize("name", ["../../evil.csv", "ABSOLUTE", "abc123.csv/../../evil.csv", "other.csv", ".."])
def test_a_worker_s_file_name_is_never_a_path_nor_another_run_s(tmp_path, name):
    from cosim.sweep.shipping import deliver

    name = str(tmp_path / "evil.csv") if name == "ABSOLUTE" else name
    runs = tmp_path / "sweep" / "runs"
    runs.mkdir(parents=True)
    with pytest.raises(SetupError) as e:
        deliver(_task(runs), {"abc123.json": b"{}", name: b"x"})
    assert str(e.value).startswith("sweep run abc123:") and repr(name) in str(e.value)
    assert _files(tmp_path) == set()   # nothing written, not even the good file
    deliver(_task(runs), {"abc123.csv": b"1", "abc123.json": b"{}"})
    assert _files(tmp_path) == {runs / "abc123.csv", runs / "abc123.json"}


pytest_plugins = ["pytester"]


def test_a_regression_reference_is_a_file_in_the_references_folder(pytester):
    pytester.makepyfile(test_ref=f"""
        def test_escape(cosim_regression):
            cosim_regression({str(SCENARIO)!r}, stop=1.0, reference="../../escaped.csv")
        """)
    pytester.makeini("[pytest]\ncosim_references = refs\n")
    outcome = pytester.runpytest_subprocess("--cosim-update-references")
    outcome.assert_outcomes(failed=1)
    outcome.stdout.fnmatch_lines(["*cosim_regression(reference=...): the reference '../../escaped.csv' cannot "
                                  "be a file name: it holds '/'*"])
    assert not list(pytester.path.parent.parent.rglob("escaped.csv"))


def test_a_journal_s_header_decides_neither_where_the_result_goes_nor_what_is_removed(tmp_path):
    """`recover` writes beside the journal and removes only FMU extraction folders, whatever the
    header says (it named the result file and the folders to delete)."""
    from cosim.record.journal import Journal, journal_path, recover

    keep = tmp_path / "precious"
    keep.mkdir()
    (keep / "file").write_text("mine")
    out = tmp_path / "runs" / "r.csv"
    out.parent.mkdir()
    journal = Journal(journal_path(out), {"output": str(tmp_path / "elsewhere.csv"), "names": ["time", "y"],
                                          "permutation": [0, 1], "temporary": [str(keep)]}, 2, 4)
    journal.window()[0] = (0.0, 1.5)
    journal.count[0] = 1
    assert recover(journal_path(out)) == (out.resolve(), 1)
    assert list(read(out)["y"]) == [1.5] and not (tmp_path / "elsewhere.csv").exists()
    assert (keep / "file").read_text() == "mine"


# --------------------------------------------------------------------------- one writer per output


# --------------------------------------------------------------------------- sweeps

def _sweep_args(scenario: Path, out: Path) -> list[str]:
    return ["sweep", str(scenario), "--set", "plant.T=15", "--stop", STOP, "-q", "--workers", "1", "-o", str(out)]


def test_a_sweep_into_a_file_is_refused_naming_it(scenario, tmp_path, capsys):
    file = tmp_path / "taken"
    file.write_text("mine")
    err = _refused(capsys, *_sweep_args(scenario, file))
    assert f"--output: {file} is a file; a sweep's output is a folder" in err
    err = _refused(capsys, *_sweep_args(scenario, file / "below"))
    assert f"{file} is a file, not a folder" in err
    assert file.read_text() == "mine"


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


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


@pytest.mark.pythonfmu
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


@pytest.mark.pythonfmu
def test_a_parameter_set_name_that_is_no_portable_file_name_is_refused(scenario, cwd, capsys):
    ssv = scenario / "case:1.ssv"
    shutil.copy(scenario / "pi_only.ssv", ssv)
    err = _refused(capsys, "run", str(scenario), "--stop", STOP, "-q", "--param-set", str(ssv))
    assert f"{ssv}, --param-set: the parameter set name 'case:1' cannot be a file name: it holds ':'" in err
    assert not (cwd / "results").exists()


@pytest.mark.pythonfmu
def test_the_sweep_s_default_folder_is_named_after_the_scenario_folder_itself(scenario, cwd, capsys):
    """``cosim sweep S/sub/..`` was results/.._sweep; the name is the resolved folder's."""
    (scenario / "sub").mkdir()
    assert main(["sweep", str(scenario / "sub" / ".."), "--set", "plant.T=15", "--stop", STOP, "-q",
                 "--workers", "1"]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (cwd / "results").iterdir()) == ["pid_fopdt_sweep"]
    assert (cwd / "results" / "pid_fopdt_sweep" / "sweep.csv").is_file()


@pytest.mark.pythonfmu
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


@pytest.mark.pythonfmu
def test_the_python_api_takes_the_same_lock(scenario, tmp_path):
    from cosim.run.simulation import simulate

    out = tmp_path / "api.csv"
    with lock_output(out), pytest.raises(SetupError) as e:
        simulate(scenario, stop_time=1.0, output=out)
    assert f"output: {out} is being written by process {os.getpid()}" in str(e.value) and not out.exists()
    assert len(simulate(scenario, stop_time=1.0, output=out)) == 11 and len(read(out)) == 11
    assert not lock_path(out).exists() and not partial_path(out).exists()


@pytest.mark.pythonfmu
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


@pytest.mark.pythonfmu
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


@pytest.mark.pythonfmu
def test_a_sweep_never_replaces_a_run_s_results_named_sweep(scenario, tmp_path, capsys):
    out = tmp_path / "mine"
    assert main(["run", str(scenario), "--stop", STOP, "-q", "-o", str(out / "sweep.csv")]) == 0
    result = (out / "sweep.csv").read_bytes()
    err = _refused(capsys, *_sweep_args(scenario, out))
    assert f"{out} holds a run's results named sweep.* ({out / 'sweep.json'} is its metadata)" in err
    assert (out / "sweep.csv").read_bytes() == result
