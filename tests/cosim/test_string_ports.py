"""A single FMU with String ports (issue 41: the Reference FMUs' Feedthrough failed `cosim run X.fmu`
with a ValueError in the recorder at 5dbfe07, its String output made a root output connector): C
FMUs of FMI 2.0 and 3.0 with a String input and output run as fmpy runs them, the Strings
exchanged (a system passes one to another component) and not recorded, with one warning naming
them; the same in a system whose root output connector a String output drives."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest

from cfmus import build_c_fmu
from cosim.cli import main
from cosim.record.results import read
from ssdgen import ssd_text, write_system

DESCRIPTION = {
    "2.0": """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Texts" guid="{7e470000-0000-4000-8000-000000000041}"
  numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Texts" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.25"/>
  <ModelVariables>
    <ScalarVariable name="name" valueReference="1" causality="input" variability="discrete"><String start="a"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="0" causality="output" variability="discrete"><String/></ScalarVariable>
    <ScalarVariable name="length" valueReference="0" causality="output" variability="discrete"><Integer/></ScalarVariable>
    <ScalarVariable name="y" valueReference="0" causality="output" variability="continuous"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2" dependencies="1"/><Unknown index="3" dependencies="1"/>
    <Unknown index="4" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
""",
    "3.0": """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Texts" instantiationToken="{7e470000-0000-4000-8000-000000000043}">
  <CoSimulation modelIdentifier="Texts" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.25"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <String name="name" valueReference="1" causality="input" variability="discrete"><Start value="a"/></String>
    <String name="label" valueReference="2" causality="output" variability="discrete"/>
    <Int32 name="length" valueReference="3" causality="output" variability="discrete"/>
    <Float64 name="y" valueReference="4" causality="output" variability="continuous"/>
  </ModelVariables>
  <ModelStructure><Output valueReference="2" dependencies="1"/><Output valueReference="3" dependencies="1"/>
    <Output valueReference="4" dependencies=""/></ModelStructure>
</fmiModelDescription>
""",
}

#: label = "<name>!" (direct feedthrough; name up to 14 characters, kept in the instance), length =
#: its length, y = time; the String functions of the version's signature (FMI 3.0's take nValues)
BODY = r"""
#define NAME(s) ((char *) (s)->bytes[1])
#define LABEL(s) ((char *) (s)->bytes[2])
static void start(S *s) { strcpy(NAME(s), "a"); }
static void calculate(S *s) {
    strcpy(LABEL(s), NAME(s)); strcat(LABEL(s), "!");
    s->i[0] = s->i[3] = (int) strlen(LABEL(s)); s->r[0] = s->r[4] = s->time; }
static int step(S *s, double t, double h) { return 0; }
static void get_strings(S *s, const VR vr[], size_t n, const char *v[]) {
    calculate(s); for (size_t k = 0; k < n; k++) v[k] = vr[k] == 1 ? NAME(s) : LABEL(s); }
static void set_strings(S *s, const VR vr[], size_t n, const char *const v[]) {
    for (size_t k = 0; k < n; k++) if (vr[k] == 1) { strncpy(NAME(s), v[k], 14); NAME(s)[14] = 0; } }
"""
STRINGS = {
    "2.0": r"""
int fmi2GetString(void *c, const VR vr[], size_t n, const char *v[]) { get_strings(c, vr, n, v); return 0; }
int fmi2SetString(void *c, const VR vr[], size_t n, const char *const v[]) { set_strings(c, vr, n, v); return 0; }
""",
    "3.0": r"""
int fmi3GetString(void *c, const VR vr[], size_t n, const char *v[], size_t nv) { get_strings(c, vr, n, v); return 0; }
int fmi3SetString(void *c, const VR vr[], size_t n, const char *const v[], size_t nv) {
    set_strings(c, vr, n, v); return 0; }
""",
}


@pytest.fixture(scope="module", params=["2.0", "3.0"])
def texts(request, tmp_path_factory):
    version = request.param
    return build_c_fmu(tmp_path_factory.mktemp(f"texts{version}"), "Texts", DESCRIPTION[version],
                       BODY + STRINGS[version], fmi=version)


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("cosim: warning:")]


def test_a_single_fmu_with_string_ports_runs_as_fmpy_runs_it(texts, tmp_path, capsys):
    assert main(["run", str(texts), "--start-value", "name=abc", "-o", str(tmp_path / "o.csv"), "-q"]) == 0, \
        capsys.readouterr().err
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1 and "exchanged, not recorded" in warned[0] and "Texts.label (String)" in warned[0] \
        and "Texts.name (String)" in warned[0], warned
    ours = read(tmp_path / "o.csv")
    theirs = fmpy.simulate_fmu(str(texts), start_values={"name": "abc"}, output_interval=0.25)
    assert "label" not in ours.dtype.names and "Texts.label" not in ours.dtype.names
    np.testing.assert_array_equal(ours["time"], theirs["time"])
    for name in ("length", "y"):
        np.testing.assert_array_equal(ours[name], theirs[name], err_msg=name)
    assert set(ours["length"]) == {4}   # "abc!": the String set reached the FMU


def test_strings_are_exchanged_in_a_system_and_a_root_output_of_one_is_not_recorded(texts, tmp_path, capsys):
    """a.label drives b.name: b.label is "<a.name>!!"; the root output connector 'shown' that
    a.label drives is named in the warning, not a column (it was a ValueError)."""
    text = ssd_text("strings", {"a": (texts.name, {"label": "output"}),
                                "b": (texts.name, {"name": "input", "length": "output"})},
                    [("a", "label", "b", "name")], stop=1.0, step=0.25)
    text = text.replace('<ssd:System name="root">', '<ssd:System name="root"><ssd:Connectors>'
                        '<ssd:Connector name="shown" kind="output"/></ssd:Connectors>').replace(
        "    </ssd:Connections>", '      <ssd:Connection startElement="a" startConnector="label" '
        'endConnector="shown"/>\n    </ssd:Connections>')
    folder = write_system(tmp_path / "sys", {texts.name: texts}, text)
    assert main(["run", str(folder), "--start-value", "a.name=xy", "-o", str(tmp_path / "s.csv"), "-q"]) == 0, \
        capsys.readouterr().err
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1 and "a.label (String)" in warned[0] and "root output 'shown'" in warned[0], warned
    result = read(tmp_path / "s.csv")
    assert "shown" not in result.dtype.names
    assert set(result["b.length"][1:]) == {4}   # "xy!!" from the second point on (a Jacobi step's delay)
