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
