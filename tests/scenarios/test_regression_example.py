"""docs/regression_example, the worked example of docs/regression.md, copied into a
fresh folder as a user copies it into their repository and run with pytest there (a subprocess): it passes
as shipped, and fails, naming the signal and the difference report, once its reference no longer matches."""
from __future__ import annotations

import shutil
from pathlib import Path

pytest_plugins = ["pytester"]

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "regression_example"


def test_the_example_passes_where_it_is_copied_and_fails_on_a_changed_reference(pytester):
    copy = pytester.path / "my_tests"
    shutil.copytree(EXAMPLE, copy)
    pytester.runpytest_subprocess("my_tests").assert_outcomes(passed=2)

    reference = copy / "test_loop" / "test_loop_follows_its_reference.csv"
    lines = reference.read_text().splitlines()
    row = next(i for i, line in enumerate(lines[1:], 1) if float(line.split(",")[0]) == 30.0)
    time, y, u = lines[row].split(",")
    lines[row] = ",".join([time, repr(float(y) * 1.01), u])             # plant.y 1 % off at 30 s
    reference.write_text("\n".join(lines) + "\n")
    failed = pytester.runpytest_subprocess("my_tests")
    failed.assert_outcomes(passed=1, failed=1)
    failed.stdout.fnmatch_lines(["*plant.y: FAILED (rtol 1e-06, atol 1e-09; on the reference's points); 1 of 601 "
                                 "points outside; first at t = 30 s*", "*difference report: *.diff.html*"])
