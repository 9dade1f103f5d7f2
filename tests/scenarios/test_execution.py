"""cosim.run.execution on its own: the time grid, and an `Execution` driven step by step on a plan
of small real FMUs, each instance kind checked against the `cosim.run.instances.Instance` protocol."""
from __future__ import annotations

import numpy as np
import pytest

from cosim.errors import RunError, SetupError
from cosim.model.grid import Grid
from cosim.run.execution import Execution
from cosim.run.program import compile
from cosim.run.instances import FMI2Instance, FMI3Instance, Instance, MEInstance
from cosim.record.observers import MemorySink, Recorder
from cosim.plan.prepare import prepare
from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus, build_test_fmus3


def test_the_grid_is_computed_and_its_last_step_ends_at_stop():
    grid = Grid(0.0, 1.05, 0.1)
    assert grid.steps == 11 and grid.time(3) == 0.30000000000000004 and grid.time(11) == 1.05
    assert Grid(0.0, 1.0, 0.1).steps == 10   # (stop − t0)/h within rounding of a whole number
    with pytest.raises(SetupError, match="not after the start time"):
        Grid(1.0, 1.0, 0.1)
    with pytest.raises(SetupError, match="positive number"):
        Grid(0.0, 1.0, float("nan"))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, built_fmus):
    found = dict(built_fmus)
    found.update(build_test_fmus(tmp_path_factory.mktemp("testfmus")))
    found.update(build_test_fmus3(tmp_path_factory.mktemp("testfmus3")))
    found["Mass_Damper"] = gemseo_fmu_dir() / "Mass_Damper.fmu"
    return found


def _plan(tmp_path, fmus, components, connections, model_exchange=(), **kw):
    files = {fmu: fmus[fmu.removesuffix(".fmu")] for fmu, _ in components.values()}
    text = ssd_text("t", components, connections, **kw)
    for name in model_exchange:
        text = text.replace(f'<ssd:Component name="{name}" ', f'<ssd:Component name="{name}" '
                            'implementation="ModelExchange" ')
    with prepare(write_system(tmp_path / "sys", files, text), use_providers=False, grid_placeholders=True) as prepared:
        return prepared.plan


def test_an_execution_steps_and_records_a_plan(tmp_path, fmus):
    plan = _plan(tmp_path, fmus, {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input",
                                                                                             "y": "output"})},
                 [("step", "y", "gain", "u")], parameters={"step": {"t_step": 0.25}, "gain": {"k": -2.0}})
    execution = Execution(plan, Grid(0.0, 0.5, 0.125))
    memory = MemorySink(None)
    try:
        execution.instantiate()
        assert all(isinstance(inst, FMI2Instance) and inst.api == "fmi2" for inst in execution.instances.values())
        names, arrays = execution.link(compile(plan)).recorder_sources()
        recorder = Recorder(names, arrays, plan.columns, [memory])
        execution.initialize()
        execution.run(recorder)
        recorder.close(execution.metadata())
    finally:
        execution.close()
    result = memory.array()
    assert execution.status == "completed" and execution.last_time == 0.5 and execution.instances == {}
    assert list(result["time"]) == [0.0, 0.125, 0.25, 0.375, 0.5]
    assert list(result["gain.y"]) == [0.0, 0.0, -2.0, -2.0, -2.0]
    meta = execution.metadata()
    assert meta["parameters"] == {"step.t_step": 0.25, "gain.k": -2.0} and meta["steps"] == 4
    assert meta["components"]["gain"]["interface"] == "fmi2-cs"


def test_every_instance_kind_is_an_instance(tmp_path, fmus):
    """FMI 2.0 CS, FMI 3.0 CS and ME instances all offer the protocol, and name their API."""
    plan = _plan(tmp_path, fmus, {"force": ("Step.fmu", {"y": "output"}),
                                  "plant": ("Mass_Damper.fmu", {"f": "input", "y": "output"}),
                                  "echo": ("Echo3.fmu", {"n": "input", "twice": "output"})},
                 [("force", "y", "plant", "f")], model_exchange=["plant"])
    execution = Execution(plan, Grid(0.0, 0.01, 0.01))
    try:
        execution.instantiate()
        kinds = {name: type(inst) for name, inst in execution.instances.items()}
        assert kinds == {"force": FMI2Instance, "plant": MEInstance, "echo": FMI3Instance}
        assert all(isinstance(inst, Instance) for inst in execution.instances.values())
        assert {name: inst.api for name, inst in execution.instances.items()} == {
            "force": "fmi2", "plant": "fmi2", "echo": "fmi3"}
        assert execution.instances["plant"].settings == plan.solvers["plant"]
    finally:
        execution.close()


def test_a_failing_step_names_the_instances_api_and_the_time(tmp_path, fmus):
    plan = _plan(tmp_path, fmus, {"f": ("Failing.fmu", {"y": "output"})}, [], parameters={"f": {"fail_time": 0.2}})
    execution = Execution(plan, Grid(0.0, 1.0, 0.1))
    try:
        execution.instantiate()
        names, arrays = execution.link(compile(plan)).recorder_sources()
        execution.initialize()
        with pytest.raises(RunError, match=r"fmi2DoStep returned Fatal at t = 0.2") as err:
            execution.run(Recorder(names, arrays, plan.columns, [MemorySink(None)]))
        assert err.value.component == "f" and execution.instances["f"].failed == "Fatal"
        assert np.isclose(execution.last_time, 0.2)
    finally:
        execution.close()
