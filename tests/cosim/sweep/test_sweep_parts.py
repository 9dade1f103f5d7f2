"""The parts of cosim.sweep on their own: values typed by their variables, each run's .ssv,
the results table, and a rerun that asks for a metric the earlier sweep did not compute."""
from __future__ import annotations

import pytest

from cosim.read import ssp
from cosim.errors import SetupError
from cosim.model.structure import ParameterValue
from cosim.sweep import read_table, sweep, write_ssv
from cosim.sweep.table import schema_of, write_table
from cosim.plan.values import typed_values
from cosim.sweep.values import Metric, parse_metric
from ssdgen import ssd_text, write_system


def test_values_take_the_type_of_their_variable():
    assert typed_values("2", "Real", "g.k") == [2.0] and typed_values("3", "Integer", "g.n") == [3]
    assert typed_values("0:1:3", "Real", "g.k") == [0.0, 0.5, 1.0]
    assert typed_values("2:6:3", "Integer", "g.n") == [2, 4, 6]
    assert typed_values("true", "Boolean", "g.b") == [True] and typed_values("x", "String", "g.s") == ["x"]
    with pytest.raises(SetupError, match="does not fall on integers"):
        typed_values("0:1:3", "Integer", "g.n")
    with pytest.raises(SetupError, match="'2.5' is not a Integer value"):
        typed_values("2.5", "Integer", "g.n")
    assert parse_metric("plant.y:setpoint.y") == Metric("plant.y", "setpoint.y")


def test_a_runs_parameter_set_reads_back_as_written(tmp_path):
    values = [ParameterValue("g.k", "Real", 0.1, "s", 0), ParameterValue("g.n", "Integer", 3, "s", 0),
              ParameterValue("g.on", "Boolean", True, "s", 0), ParameterValue("g.s", "String", "a b", "s", 0)]
    write_ssv(tmp_path / "run.ssv", values, name="run")
    assert [(p.name, p.type, p.value) for p in ssp.read_ssv(tmp_path / "run.ssv")] == [
        (p.name, p.type, p.value) for p in values]


def test_the_table_keeps_the_types_of_its_columns(tmp_path):
    schema = schema_of({"g.k": "Real", "g.n": "Integer"}, True, [Metric("y", "r")])
    rows = [{"run_id": "a", "g.k": 1.5, "g.n": 2, "seed": 7, "status": "completed", "message": None, "error": None,
             "wall_time": 0.1, **{c: 1.0 for c in Metric("y", "r").columns()},
             Metric("y", "r").reason_column(): "settling_time: the signal never settles"}]
    write_table(rows, schema, tmp_path / "sweep.csv", tmp_path / "sweep.parquet")
    assert read_table(tmp_path / "sweep.parquet") == rows
    assert (tmp_path / "sweep.csv").read_text().splitlines()[0].startswith('"run_id","g.k","g.n","seed"')


def test_a_rerun_computes_a_new_metric_from_the_kept_results(tmp_path, twin_fmus):
    text = ssd_text("pair", {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input",
                                                                                        "y": "output"})},
                    [("step", "y", "gain", "u")], stop=4.0, step=0.1, parameters={"step": {"t_step": 1.0}})
    folder = write_system(tmp_path / "pair", {"Step.fmu": twin_fmus["Step"], "Gain.fmu": twin_fmus["Gain"]}, text)
    first = sweep(folder, {"gain.k": ["1", "2"]}, output=tmp_path / "out", executor="serial")
    again = sweep(folder, {"gain.k": ["1", "2"]}, metrics=["gain.y:step.y"], output=tmp_path / "out",
                  executor="serial")
    assert (first.ran, again.ran, again.skipped) == (2, 0, 2)
    overshoot = [row["gain.y:overshoot"] for row in again.rows]
    assert overshoot[0] == pytest.approx(0.0, abs=1e-9) and overshoot[1] == pytest.approx(100.0)
