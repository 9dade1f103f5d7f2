"""Warnings where a loop changes silently (issue 45, `cosim.plan.loopcheck`): from the FMUs' own
org.greyfmu annotation, one ``cosim: warning:`` line each naming the component and the variable;
``--strict`` makes them errors (exit 2).  pid_fopdt and swaps of its controller; each check
prepares the plan (nothing is run) but the two CLI ones.  About 6 s."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import pytest

from cosim.errors import CosimWarning
from cosim.plan.loopcheck import LoopWarning
from cosim.plan.prepare import prepare
from runhelpers import cli_exit, refused

SCENARIO = Path("ssp/pid_fopdt")


def findings(path, **options) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CosimWarning)
        with prepare(path, **options):
            pass
    return [str(w.message) for w in caught if issubclass(w.category, LoopWarning)]


@pytest.fixture(scope="module")
def swapped(tmp_path_factory, built_fmus) -> Path:
    """pid_fopdt with its controller binding removed: a folder whose SSD names CONTROLLER.fmu."""
    text = (SCENARIO / "SystemStructure.ssd").read_text()
    text = re.sub(r'\s*<ssd:ParameterBindings>\s*<ssd:ParameterBinding source="controller.ssv"/>\s*'
                  r'</ssd:ParameterBindings>', "", text)
    folder = tmp_path_factory.mktemp("swap")
    (folder / "template.ssd").write_text(text)
    return folder


def with_controller(folder: Path, name: str) -> Path:
    ssd = folder / f"{name}.ssd"
    ssd.write_text((folder / "template.ssd").read_text().replace("resources/PID.fmu", f"resources/{name}.fmu"))
    return ssd


def test_the_main_scenario_warns_of_nothing(built_fmus):
    assert findings(SCENARIO) == []


def test_a_master_step_longer_than_the_sample_time(built_fmus):
    (message,) = findings(SCENARIO, step_size=0.3)
    assert message.startswith("the master step 0.3 s is longer than controller.Ts = 0.1 s: PID.fmu makes up to 3 "
                              "samples per step"), message


def test_a_master_step_that_does_not_divide_the_sample_time(built_fmus):
    (message,) = findings(SCENARIO, step_size=0.3, start_values=["controller.Ts=1"])
    assert "the master step 0.3 s does not divide controller.Ts = 1 s" in message and "--step 0.25" in message
    assert findings(SCENARIO, step_size=0.25, start_values=["controller.Ts=1"]) == []


def test_a_swap_that_keeps_the_new_controllers_default_sample_time(swapped):
    (message,) = findings(with_controller(swapped, "GrayPredictivePI"))
    assert message.startswith("controller.Ts = 1 s is GrayPredictivePI.fmu's default (no parameter binding sets it), "
                              "not the master step 0.1 s"), message
    assert findings(with_controller(swapped, "GrayPredictivePI"), start_values=["controller.Ts=1"]) == []


def test_an_unconnected_input_the_law_reads_under_its_condition(swapped):
    ssd = with_controller(swapped, "GainScheduledPID")
    (message,) = findings(ssd)
    assert message.startswith("controller.W is not connected: GainScheduledPID.fmu reads it as its scheduling input "
                              "(law = 3); it keeps its start value 0"), message
    itae = findings(ssd, start_values=["controller.law=4"])
    assert [m.split(" is not connected")[0] for m in itae] == ["controller.Kp", "controller.T", "controller.tau"]
    assert findings(ssd, start_values=["controller.W=1"]) == []   # a value bound: a choice, not an oversight


def test_the_cli_prints_one_line_each_and_strict_refuses(capsys, built_fmus, tmp_path):
    out = tmp_path / "r.csv"
    err = cli_exit(capsys, 0, "run", str(SCENARIO), "--step", "0.3", "--stop", "1", "-o", str(out), "--quiet")
    assert err.count("cosim: warning:") == 1 and "controller.Ts = 0.1 s" in err
    err = refused(capsys, "run", str(SCENARIO), "--step", "0.3", "--stop", "1", "-o", str(out), "--strict")
    assert "controller.Ts = 0.1 s" in err and "(--strict makes this warning an error)" in err


def test_the_python_api_and_the_regression_fixture_warn_too(built_fmus):
    """cosim.simulate (which cosim_regression calls) prepares through cosim.plan.prepare.prepare."""
    import cosim

    with pytest.warns(LoopWarning, match="controller.Ts = 0.1 s"):
        cosim.simulate(SCENARIO, stop_time=1.0, step_size=0.3)
