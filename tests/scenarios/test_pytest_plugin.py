"""The pytest plugin cosim.pytest_plugin (loaded through the ``pytest11`` entry point) as a user's suite
sees it: pytester writes a user test using ``cosim_regression`` on ssp/pid_fopdt and runs pytest on it.

pytest runs in a subprocess each time: an in-process run removes the modules it imported when it ends, and the
pythonfmu FMUs, which share this interpreter, then fail to import numpy again ("cannot load module more than
once per process")."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

SCENARIO = Path(__file__).resolve().parents[2] / "ssp" / "pid_fopdt"
STOP = 20.0   # 200 steps of 0.1 s; the setpoint steps at 10 s, so plant.y moves in the second half


def user_test(pytester: pytest.Pytester, tolerances: dict | None = None) -> None:
    """A user's test file (absolute scenario path: pytester runs in a temporary folder)."""
    pytester.makepyfile(test_loop=f"""
        def test_loop(cosim_regression):
            result = cosim_regression({str(SCENARIO)!r}, stop={STOP!r}, signals=["plant.y", "controller.u"],
                                      tolerances={tolerances!r})
            assert result["time"][-1] == {STOP!r}
        """)


def alter(reference: Path, signal: str, time: float, factor: float) -> None:
    """Multiply one sample of a reference CSV by ``factor``."""
    lines = reference.read_text().splitlines()
    column = [name.strip('"') for name in lines[0].split(",")].index(signal)
    for i, line in enumerate(lines[1:], start=1):
        cells = line.split(",")
        if float(cells[0]) == time:
            cells[column] = repr(float(cells[column]) * factor)
            lines[i] = ",".join(cells)
            break
    else:
        raise AssertionError(f"no sample at {time} s in {reference}")
    reference.write_text("\n".join(lines) + "\n")


def junit_properties(path: Path) -> dict[str, str]:
    from xml.etree import ElementTree

    return {p.get("name"): p.get("value") for p in ElementTree.parse(path).iter("property")}


def test_reference_missing_written_checked_altered_and_loosened(pytester):
    """One reference's life, each step a pytest run in a subprocess, the references in the folder the ini
    option cosim_references names: missing (fails, says how to write it),
    written with --cosim-update-references (passes, listed in the summary), checked (passes, the per-signal
    verdicts in the JUnit XML), altered (fails naming signal, first and worst violation, tube and the
    difference report, HTML and PNG), rewritten (the summary says what changed), accepted with a looser
    per-signal tolerance."""
    user_test(pytester)
    pytester.makeini("[pytest]\ncosim_references = regression_refs\n")
    reference = pytester.path / "regression_refs" / "test_loop.csv"

    missing = pytester.runpytest_subprocess()
    missing.assert_outcomes(failed=1)
    missing.stdout.fnmatch_lines(["*no reference for*test_loop.csv*--cosim-update-references*"])
    assert not reference.exists()

    written = pytester.runpytest_subprocess("--cosim-update-references")
    written.assert_outcomes(passed=1)
    written.stdout.fnmatch_lines(["*cosim: 1 reference(s) written*",
                                  f"written {reference} (test_loop.py::test_loop): new"])
    lines = reference.read_text().splitlines()
    assert lines[0] == '"time","plant.y","controller.u"'      # only the selected signals
    assert len(lines) == 1 + round(STOP / 0.1) + 1

    pytester.runpytest_subprocess("--junitxml=passed.xml").assert_outcomes(passed=1)
    verdicts = junit_properties(pytester.path / "passed.xml")
    assert verdicts["cosim plant.y"].startswith("plant.y: passed (rtol 1e-06, atol 1e-09; on the reference's points)")
    assert verdicts["cosim controller.u"].startswith("controller.u: passed")

    original = reference.read_text()
    alter(reference, "plant.y", 15.0, 1 + 1e-3)
    failed = pytester.runpytest_subprocess("--junitxml=failed.xml")
    failed.assert_outcomes(failed=1)
    failed.stdout.fnmatch_lines([
        f"*1 of 2 signals differ from the reference for {SCENARIO} (reference {reference}; candidate *.csv)*",
        "*plant.y: FAILED (rtol 1e-06, atol 1e-09; on the reference's points); 1 of 201 points outside; first at "
        "t = 15 s: run *, reference *, tube * (outside by *e-05); worst at t = 15 s*",
        "*difference report: *test_loop.diff.html (plot *test_loop.diff.png)*",
    ])
    text = failed.stdout.str()
    candidate = Path(text.split("; candidate ")[1].split(")")[0])
    assert candidate.is_file()                                  # the run's own CSV, left for inspection
    page = Path(text.split("difference report: ")[1].split(" (plot ")[0])
    assert page.is_file() and page.with_suffix(".png").stat().st_size > 10_000
    assert "plant.y: FAILED" in page.read_text()
    assert junit_properties(pytester.path / "failed.xml")["cosim plant.y"].startswith("plant.y: FAILED")

    rewritten = pytester.runpytest_subprocess("--cosim-update-references")      # accept the run again
    rewritten.assert_outcomes(passed=1)
    rewritten.stdout.fnmatch_lines([f"rewritten {reference} (test_loop.py::test_loop): changed: plant.y (worst "
                                    "|new − old| *e-05 at t = 15 s)"])
    assert reference.read_text() == original

    alter(reference, "plant.y", 15.0, 1 + 1e-3)
    user_test(pytester, tolerances={"plant.*": (1e-2, 0.0)})
    pytester.runpytest_subprocess().assert_outcomes(passed=1)

    # the exact name is more specific than the glob and keeps plant.y tight
    user_test(pytester, tolerances={"plant.*": (1e-2, 0.0), "plant.y": {"rtol": 1e-7}})
    tight = pytester.runpytest_subprocess()
    tight.assert_outcomes(failed=1)
    tight.stdout.fnmatch_lines(["*plant.y: FAILED (rtol 1e-07, atol 1e-09; on the reference's points)*first at "
                                "t = 15 s*"])


def test_metric_targets_fail_with_the_measured_value_and_pass_on_it(pytester):
    """metrics={signal: {metric: (expected, tolerance)}} with no samples compared (signals=[]): a missed
    target fails naming the measured value and the loop's set-point step; that value passes."""
    def targets(overshoot: float, tolerance: float) -> None:
        pytester.makepyfile(test_loop=f"""
            def test_loop(cosim_regression):
                cosim_regression({str(SCENARIO)!r}, stop=140.0, signals=[],
                                 metrics={{"plant.y": {{"overshoot": ({overshoot!r}, {tolerance!r}), "IAE": (0.0, 1e9)}}}})
            """)

    targets(99.0, 1e-9)
    missed = pytester.runpytest_subprocess()
    missed.assert_outcomes(failed=1)
    missed.stdout.fnmatch_lines(["*1 of 2 metric targets missed*",
                                 "*plant.y overshoot: FAILED, measured *, expected 99 ± 1e-09 (from the last "
                                 "change of setpoint.y)*", "*difference report: *"])
    measured = float(missed.stdout.str().split("overshoot: FAILED, measured ")[1].split(",")[0])
    assert 0 < measured < 99
    assert not list(pytester.path.glob("**/test_loop.csv"))     # no samples compared, no reference
    targets(measured, 1e-4)                                   # printed to 6 digits
    pytester.runpytest_subprocess().assert_outcomes(passed=1)


def test_what_a_rewrite_changes_is_said_in_one_line(tmp_path):
    """The summary line of --cosim-update-references (`changes`): new, added/removed signals, the signals
    out of tolerance with their largest difference, or none."""
    import numpy as np

    from cosim.pytest_plugin import changes
    from cosim.record.results import write

    t = np.arange(0, 1.0001, 0.1)
    old = np.zeros(len(t), dtype=[("time", float), ("a", float), ("b", float)])
    old["time"], old["a"], old["b"] = t, t, 1.0
    path = tmp_path / "ref.csv"
    rule = {"tolerances": {"b": (0.0, 0.5)}, "rtol": 1e-6, "atol": 1e-9, "time": 0.0, "mode": "tube"}
    assert changes(path, old, ["a", "b"], rule) == "new"
    write(old, path)
    assert changes(path, old, ["a", "b"], rule) == "no signal out of tolerance"
    new = old.copy()
    new["a"][4] += 0.25
    new["b"] += 0.4                                           # within b's own tolerance
    assert changes(path, new, ["a"], rule) == "removed: b; changed: a (worst |new − old| 0.25 at t = 0.4 s)"


def test_option_and_ini_listed_in_help(pytester):
    result = pytester.runpytest("--help")      # in process: runs no FMU
    result.stdout.fnmatch_lines(["*--cosim-update-references*", "*cosim_references*"])


def test_plugin_module_imports_neither_numpy_nor_fmpy(pytester):
    """pytest loads the plugin in every session of anyone who installs the package: it must stay cheap."""
    result = pytester.run(sys.executable, "-c", "import sys, cosim.pytest_plugin; "
                          "print(sorted(m for m in ('numpy', 'fmpy', 'cosim.run.simulation') if m in sys.modules))")
    assert result.ret == 0
    assert result.stdout.lines[-1] == "[]"


def test_references_default_beside_the_test_file(pytester):
    """Issue 27, item 4: without the ini option a reference lands beside the user's test file, in a folder
    named after it (pytest-regressions' convention), not in the rootdir's tests/references."""
    sub = pytester.mkdir("my_tests")
    (sub / "test_mine.py").write_text(
        "def test_loop(cosim_regression):\n"
        f"    cosim_regression({str(SCENARIO)!r}, stop=1.0, signals=['plant.y'])\n")
    written = pytester.runpytest_subprocess("--cosim-update-references")
    written.assert_outcomes(passed=1)
    assert (sub / "test_mine" / "test_loop.csv").is_file()
    assert not (pytester.path / "tests" / "references").exists()
    pytester.runpytest_subprocess().assert_outcomes(passed=1)


def test_a_conftest_fixture_chooses_the_references_folder(pytester):
    """The folder is the cosim_references_dir fixture's: a conftest overrides it (as tests/conftest.py does
    to keep this repository's references in tests/references)."""
    pytester.makeconftest("import pytest\n\n@pytest.fixture\ndef cosim_references_dir(tmp_path_factory):\n"
                          "    from pathlib import Path\n    return Path.cwd() / 'kept_here'\n")
    pytester.makepyfile(test_loop="def test_loop(cosim_regression):\n"
                                  f"    cosim_regression({str(SCENARIO)!r}, stop=1.0, signals=['plant.y'])\n")
    pytester.runpytest_subprocess("--cosim-update-references").assert_outcomes(passed=1)
    assert (pytester.path / "kept_here" / "test_loop.csv").is_file()
