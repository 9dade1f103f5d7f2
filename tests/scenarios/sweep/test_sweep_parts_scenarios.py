"""The tests of tests/cosim/sweep/test_sweep_parts.py that need pythonfmu: they run our FMUs (fmus/, greyfmu build) or the scenarios of ssp/."""
from __future__ import annotations

import pytest

from cosim.sweep import sweep
from ssdgen import ssd_text, write_system


def test_a_rerun_computes_a_new_metric_from_the_kept_results(tmp_path, built_fmus):
    text = ssd_text("pair", {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input",
                                                                                        "y": "output"})},
                    [("step", "y", "gain", "u")], stop=4.0, step=0.1, parameters={"step": {"t_step": 1.0}})
    folder = write_system(tmp_path / "pair", {"Step.fmu": built_fmus["Step"], "Gain.fmu": built_fmus["Gain"]}, text)
    first = sweep(folder, {"gain.k": ["1", "2"]}, output=tmp_path / "out", executor="serial")
    again = sweep(folder, {"gain.k": ["1", "2"]}, metrics=["gain.y:step.y"], output=tmp_path / "out",
                  executor="serial")
    assert (first.ran, again.ran, again.skipped) == (2, 0, 2)
    overshoot = [row["gain.y:overshoot"] for row in again.rows]
    assert overshoot[0] == pytest.approx(0.0, abs=1e-9) and overshoot[1] == pytest.approx(100.0)
