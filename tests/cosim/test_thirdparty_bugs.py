"""What FMUs written by other tools exposed (issue 21, items 1-4), each on an FMU that
reproduces it: a String parameter on FMI 2.0, the last valid sample when an FMU ends the run
(FMI 2.0 Discard with fmi2LastSuccessfulTime = end of step, FMI 3.0 OK with
terminateSimulation), the refusal of a Scheduled-Execution-only FMI 3.0 FMU.  The FMUs that
end the run are C FMUs compiled here (tests/cfmus.py); fmpy.simulate_fmu is the reference."""
from __future__ import annotations

import json

import fmpy
import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from ssdgen import ssd_text, write_system
from cosim.errors import SetupError
from testfmus import build_test_fmus, build_test_fmus3, edited_copy

ENDS2 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Ends" guid="{5c3a1e00-0000-4000-8000-000000000021}"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Ends" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <ScalarVariable name="y" valueReference="0" causality="output" variability="continuous"><Real/></ScalarVariable>
    <ScalarVariable name="tEnd" valueReference="1" causality="parameter" variability="fixed" initial="exact">
      <Real start="9"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""

ENDS3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Ends3" instantiationToken="{5c3a1e00-0000-4000-8000-000000000023}">
  <CoSimulation modelIdentifier="Ends3" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="y" valueReference="0" causality="output" variability="continuous"/>
    <Float64 name="tEnd" valueReference="1" causality="parameter" variability="fixed" start="9"/>
  </ModelVariables>
  <ModelStructure><Output valueReference="0" dependencies=""/></ModelStructure>
</fmiModelDescription>
"""

#: y = time; the step that reaches tEnd asks to end the run (FMI 2.0: Discard, FMI 3.0: the given status)
ENDS_BODY = """
static void start(S *s) { s->r[1] = 9.0; }
static void calculate(S *s) { s->r[0] = s->time; }
static int step(S *s, double t, double h) {
    if (t + h >= s->r[1] - 1e-9) { s->terminate = 1; return END_STATUS; }
    return 0; }
"""


@pytest.fixture(scope="module")
def ends(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ends")
    return {"Ends": build_c_fmu(tmp, "Ends", ENDS2, "#define END_STATUS 2\n" + ENDS_BODY, "2.0"),
            "Ends3": build_c_fmu(tmp, "Ends3", ENDS3, "#define END_STATUS 0\n" + ENDS_BODY, "3.0")}


@pytest.mark.parametrize("name", ["Ends", "Ends3"])
def test_the_step_that_ends_the_run_is_recorded(tmp_path, ends, name):
    """fmpy records 46 samples ending at t = 9 (step 0.2); so must cosim, and say why it stopped."""
    fmu = ends[name]
    ref = fmpy.simulate_fmu(str(fmu), stop_time=10.0, output_interval=0.2, output=["y"])
    folder = write_system(tmp_path / "s", {fmu.name: fmu},
                          ssd_text("ends", {"e": (fmu.name, {"y": "output"})}, [], stop=10.0, step=0.2))
    out = tmp_path / "out.csv"
    res = cosim.simulate(folder, output=out)
    assert len(ref) == 46 and ref["time"][-1] == pytest.approx(9.0)
    assert len(res) == len(ref)
    np.testing.assert_allclose(res["time"], ref["time"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(res["e.y"], ref["y"])
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "terminated" and meta["last_time"] == pytest.approx(9.0)
    expected = "fmi2Terminated = true and fmi2LastSuccessfulTime = 9" if name == "Ends" \
        else "fmi3DoStep returned OK with terminateSimulation = true"
    assert expected in meta["message"] and "component 'e'" in meta["message"]


def test_a_discard_inside_the_step_ends_at_the_last_good_time(tmp_path, ends):
    """fmi2LastSuccessfulTime before the end of the step: no valid communication point there."""
    fmu = build_c_fmu(tmp_path, "Ends", ENDS2, "#define END_STATUS 2\n" + ENDS_BODY.replace(
        "s->terminate = 1;", "s->terminate = 1; s->last = t + h / 2;"), "2.0")
    folder = write_system(tmp_path / "s", {fmu.name: fmu},
                          ssd_text("ends", {"e": (fmu.name, {"y": "output"})}, [], stop=10.0, step=0.2))
    with pytest.warns(RuntimeWarning, match=r"fmi2LastSuccessfulTime = 8\.9 at t = 8\.8 .*last good time 8\.8"):
        res = cosim.simulate(folder)
    assert len(res) == 45 and res["time"][-1] == pytest.approx(8.8)


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


@pytest.fixture(scope="module")
def pyfmus(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pyfmus")
    return {**build_test_fmus(tmp / "fmi2"), **build_test_fmus3(tmp / "fmi3")}


@pytest.mark.pythonfmu
def test_string_parameter_on_fmi2(tmp_path, pyfmus):
    """A String binding reaches an FMI 2.0 FMU (Labels: length = len(text))."""
    comps = {"lab": ("Labels.fmu", {"text": "input", "length": "output"})}
    folder = write_system(tmp_path / "s", {"Labels.fmu": pyfmus["Labels"]},
                          ssd_text("str", comps, [], stop=0.2, step=0.1, parameters={"lab": {"text": "abcde"}}))
    res = cosim.simulate(folder)
    np.testing.assert_array_equal(res["lab.length"], 5)


@pytest.mark.pythonfmu
def test_scheduled_execution_only_fmi3_is_refused_as_such(tmp_path, pyfmus):
    """An FMI 3.0 FMU with only <ScheduledExecution>: the refusal names that interface."""
    se = edited_copy(pyfmus["Echo3"], tmp_path / "SE.fmu",
                     lambda text: text.replace("<CoSimulation", "<ScheduledExecution"))
    comps = {"e": ("SE.fmu", {})}
    folder = write_system(tmp_path / "s", {"SE.fmu": se}, ssd_text("se", comps, [], stop=0.2, step=0.1))
    with pytest.raises(SetupError, match="only a Scheduled Execution interface") as refused:
        cosim.simulate(folder)
    assert "Model Exchange" not in str(refused.value).split("only a Scheduled")[0]
