"""FMI 3.0 arrays in the master (issue 41: MapleSim's CoupledClutches `outputs`, a Float64 array of
4, was silently dropped by `cosim run X.fmu` at 5dbfe07).  A C FMU compiled here (tests/cfmus.py)
with a 1-D output array of 4, a 2-D one (2×3), one whose extent is a structural parameter, an
Int32 array, a 1-D input array and a String array: each element is recorded under the name fmpy
and fmusim give it (``outputs[1]``, ``A[2,3]``, row-major, 1-based), equal sample by sample to
fmpy.simulate_fmu's shaped columns; elements and whole arrays of equal shape connect in an SSD;
the names work in --signals, tolerance keys and input tables; the String array, not recorded, is
named in one warning."""
from __future__ import annotations

import itertools

import fmpy
import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from cosim.cli import main
from cosim.errors import SetupError
from cosim.present.plots import default_panels, plotted
from cosim.record.metadata import signal_info
from cosim.record.results import read
from ssdgen import ssd_text, write_system

def _description(name: str, token: str, variables: str, structure: str) -> str:
    """An FMI 3.0 Co-Simulation model description with ``time`` (value reference 63) and ``variables``,
    run from 0 to 1 s by steps of 0.25 s."""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{{{token}}}">
  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.25"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
{variables}  </ModelVariables>
  <ModelStructure>{structure}</ModelStructure>
</fmiModelDescription>
"""


ARRAYS3 = _description("Arrays3", "a7a70000-0000-4000-8000-000000000041", """\
    <UInt64 name="n" valueReference="1" causality="structuralParameter" variability="fixed" start="3"/>
    <Float64 name="u" valueReference="2" causality="input" variability="continuous" start="1 2">
      <Dimension start="2"/></Float64>
    <Float64 name="outputs" valueReference="10" causality="output" variability="continuous">
      <Dimension start="4"/></Float64>
    <Float64 name="A" valueReference="20" causality="output" variability="continuous">
      <Dimension start="2"/><Dimension start="3"/></Float64>
    <Float64 name="x" valueReference="30" causality="output" variability="continuous">
      <Dimension valueReference="1"/></Float64>
    <Int32 name="counts" valueReference="40" causality="output" variability="discrete">
      <Dimension start="3"/></Int32>
    <Float64 name="w" valueReference="45" causality="output" variability="continuous">
      <Dimension start="2"/></Float64>
    <Boolean name="flags" valueReference="55" causality="output" variability="discrete">
      <Dimension start="2"/></Boolean>
    <String name="labels" valueReference="50" causality="output" variability="discrete">
      <Dimension start="2"/></String>
    <Float64 name="y" valueReference="60" causality="output" variability="continuous"/>
""", """
    <Output valueReference="10" dependencies="2"/><Output valueReference="20" dependencies=""/>
    <Output valueReference="30" dependencies=""/><Output valueReference="40" dependencies=""/>
    <Output valueReference="45" dependencies=""/><Output valueReference="50" dependencies=""/>
    <Output valueReference="55" dependencies=""/><Output valueReference="60" dependencies="2"/>
""")

#: k = steps taken, t = time: outputs[e] = e·t + u[1] (e = 1..4), A[i,j] = 10 i + j + k,
#: x[e] = e·k/2 (e = 1..n, n = 3), counts[e] = e·k, w = (t, -t), flags = (k odd, k even),
#: y = u[1] + 10 u[2]
ARRAYS3_BODY = r"""
static void start(S *s) {
    s->l[1] = 3; s->extent[2] = 2; s->r[2] = 1; s->r[3] = 2; s->extent[10] = 4; s->extent[20] = 6;
    s->extent[30] = (size_t) s->l[1]; s->extent[40] = 3; s->extent[45] = 2; s->extent[55] = 2; }
static void calculate(S *s) {
    double k = (double) s->l[62], t = s->time;
    for (int e = 0; e < 4; e++) s->r[10 + e] = (e + 1) * t + s->r[2];
    for (int i = 0; i < 2; i++) for (int j = 0; j < 3; j++) s->r[20 + 3 * i + j] = 10 * (i + 1) + (j + 1) + k;
    for (int e = 0; e < (int) s->l[1]; e++) s->r[30 + e] = (e + 1) * k / 2;
    for (int e = 0; e < 3; e++) s->i[40 + e] = (e + 1) * (int) k;
    s->r[45] = t; s->r[46] = -t; s->b[55] = (int) k % 2; s->b[56] = !s->b[55]; s->r[60] = s->r[2] + 10 * s->r[3]; }
static int step(S *s, double t, double h) { s->l[62] += 1; return 0; }
"""

#: the recorded element columns of each output array, as fmpy and fmusim name them
ELEMENTS = {"outputs": [f"outputs[{e}]" for e in range(1, 5)],
            "A": [f"A[{i},{j}]" for i, j in itertools.product((1, 2), (1, 2, 3))],
            "x": ["x[1]", "x[2]", "x[3]"], "counts": ["counts[1]", "counts[2]", "counts[3]"], "w": ["w[1]", "w[2]"],
            "flags": ["flags[1]", "flags[2]"]}


@pytest.fixture(scope="module")
def arrays3(tmp_path_factory):
    return build_c_fmu(tmp_path_factory.mktemp("arrays3"), "Arrays3", ARRAYS3, ARRAYS3_BODY, fmi="3.0")


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("cosim: warning:")]


def _assert_elements_equal(ours: np.ndarray, theirs: np.ndarray, prefix: str = "") -> None:
    """Each element column of ours equals its place in fmpy's shaped column (row-major)."""
    for array, names in ELEMENTS.items():
        flat = theirs[array].reshape(len(theirs), -1)
        assert flat.shape[1] == len(names)
        for position, name in enumerate(names):
            np.testing.assert_array_equal(ours[prefix + name], flat[:, position], err_msg=name)


def test_a_single_fmu_records_every_array_element_as_fmpy(arrays3, tmp_path, capsys):
    """`cosim run X.fmu`: every element of every numeric output and input array is a column named
    as fmpy and fmusim name it, equal to fmpy.simulate_fmu's; the String array is named in the one
    'exchanged, not recorded' warning."""
    assert main(["run", str(arrays3), "-o", str(tmp_path / "o.csv"), "-q"]) == 0, capsys.readouterr().err
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1 and "Arrays3.labels (String array of 2)" in warned[0], warned
    ours = read(tmp_path / "o.csv")
    theirs = fmpy.simulate_fmu(str(arrays3), output_interval=0.25)
    np.testing.assert_array_equal(ours["time"], theirs["time"])
    _assert_elements_equal(ours, theirs)
    _assert_elements_equal(ours, theirs, prefix="Arrays3.")
    np.testing.assert_array_equal(ours["y"], theirs["y"])
    np.testing.assert_array_equal(ours["Arrays3.u[2]"], 2.0)
    assert ours["A[2,3]"][-1] == 23 + 4 and ours["x[3]"][-1] == 3 * 4 / 2   # k = 4 steps at t = 1
    with cosim.prepare(arrays3) as prepared:   # the default plot: an array's elements in one panel
        outputs, inputs = prepared.plan.recorded()
        panels = default_panels(signal_info(prepared.plan), plotted(prepared.plan, outputs + inputs))
    assert [len(p) for p in panels] == [4, 6, 3, 3, 2, 2, 1, 2] and panels[1][-1] == "Arrays3.A[2,3]", panels


def test_array_element_names_work_in_signals_tolerances_and_input_tables(arrays3, tmp_path, capsys):
    """--signals with an element (a comma inside the brackets is no panel separator, brackets are
    no glob class), an input table driving u[2], compare with a tolerance key on A[*], metrics of
    an element."""
    table = tmp_path / "in.csv"
    table.write_text('time,"u[2]"\n0,5\n0.5,5\n0.5,7\n1,7\n')   # 5, then 7 from t = 0.5 on
    out = tmp_path / "o.csv"
    assert main(["run", str(arrays3), "--input-file", str(table), "-o", str(out), "-q",
                 "--plot", str(tmp_path / "o.png"), "--signals", "A[2,3],outputs[1]", "x[*]"]) == 0, \
        capsys.readouterr().err
    ours = read(out)
    # y = u[1] + 10 u[2], recorded before the table's value at t is set (cosim.plan.inputs)
    np.testing.assert_array_equal(ours["y"], 1 + 10 * np.where(ours["time"] > 0.5, 7.0, 5.0))
    assert (tmp_path / "o.png").stat().st_size > 1000
    shifted = ours.copy()
    shifted["A[1,1]"] += 1e-3
    read_back = tmp_path / "shifted.csv"
    from cosim.record.results import write
    write(shifted, read_back)
    assert main(["compare", str(out), str(read_back), "--tolerance", "A[*]=1e-2,0"]) == 0, capsys.readouterr()
    assert main(["compare", str(out), str(read_back), "--signals", "A[1,1]"]) == 1
    assert main(["metrics", str(out), "--signal", "A[2,3]", "--setpoint", "y", "--t0", "0", "--t1", "1"]) == 0
    assert "A[2,3] following y" in capsys.readouterr().out


def _system(tmp_path, arrays3, components, connections):
    text = ssd_text("arrays", components, connections, stop=1.0, step=0.25)
    return write_system(tmp_path / "sys", {arrays3.name: arrays3}, text)


def test_elements_and_whole_arrays_of_equal_shape_connect(arrays3, tmp_path):
    """a.w (2) drives b.u (2) as a whole array, a.A[2,3] drives the 2-D element c.u[1]; b and c
    record their input elements and the outputs that follow from them."""
    comps = {"a": ("Arrays3.fmu", {"w": "output", "A[2,3]": "output", "A": "output"}),
             "b": ("Arrays3.fmu", {"u": "input", "y": "output"}),
             "c": ("Arrays3.fmu", {"u[1]": "input", "outputs": "output"})}
    folder = _system(tmp_path, arrays3, comps, [("a", "w", "b", "u"), ("a", "A[2,3]", "c", "u[1]")])
    r = cosim.simulate(folder)
    assert [n for n in r.dtype.names if n.startswith("a.A[")] == ["a.A[2,3]"] + [f"a.{n}" for n in ELEMENTS["A"]
                                                                              if n != "A[2,3]"]
    t = r["time"]
    np.testing.assert_array_equal(r["b.u[1]"], r["a.w[1]"])
    np.testing.assert_array_equal(r["b.u[2]"], -t)
    np.testing.assert_array_equal(r["b.y"], r["a.w[1]"] + 10 * r["a.w[2]"])
    np.testing.assert_array_equal(r["c.u[1]"], r["a.A[2,3]"])
    np.testing.assert_array_equal(r["c.outputs[3]"], 3 * t + r["c.u[1]"])


@pytest.mark.parametrize("connection, message", [
    (("a", "outputs", "b", "u"), "a.outputs (an array of 4 values) and b.u (an array of 2 values)"),
    (("a", "A", "b", "u"), "a.A (an array of 2×3 values) and b.u (an array of 2 values)"),
    (("a", "y", "b", "u"), "a.y (a scalar) and b.u (an array of 2 values)"),
])
def test_whole_arrays_of_different_shapes_are_refused(arrays3, tmp_path, connection, message):
    comps = {"a": ("Arrays3.fmu", {connection[1]: "output"}), "b": ("Arrays3.fmu", {"u": "input"})}
    with pytest.raises(SetupError) as error:
        cosim.prepare(_system(tmp_path, arrays3, comps, [connection]))
    assert message in str(error.value) and "line " in str(error.value)


def test_a_system_connector_of_one_value_feeding_a_whole_array_is_refused(arrays3, tmp_path):
    """An undriven root input connector r wired to b.u (2 values): an input table column or a
    ParameterBinding gives r one value, which no element order can spread over u."""
    text = ssd_text("arrays", {"b": ("Arrays3.fmu", {"u": "input"})}, [], stop=1.0, step=0.25)
    text = text.replace('<ssd:System name="root">', '<ssd:System name="root"><ssd:Connectors>'
                        '<ssd:Connector name="r" kind="input"/></ssd:Connectors>').replace(
        "    </ssd:Elements>\n", '    </ssd:Elements>\n    <ssd:Connections><ssd:Connection startConnector="r" '
        'endElement="b" endConnector="u"/></ssd:Connections>\n')
    folder = write_system(tmp_path / "sys", {arrays3.name: arrays3}, text)
    with pytest.raises(SetupError) as error:
        cosim.prepare(folder)
    assert "system connector 'r' holds one value and feeds b.u, an array of 2 values" in str(error.value)


@pytest.mark.parametrize("connector, message", [
    ("A[3,1]", "A[1,1] .. A[2,3]"), ("A[2]", "A[1,1] .. A[2,3]"), ("x[4]", "x[1] .. x[3]"),
    ("A[2, 3]", "A[2,3]"),
])
def test_elements_outside_an_array_are_refused_with_its_shape(arrays3, tmp_path, connector, message):
    comps = {"a": ("Arrays3.fmu", {connector: "output"})}
    with pytest.raises(SetupError) as error:
        cosim.prepare(_system(tmp_path, arrays3, comps, []))
    assert message in str(error.value) and connector in str(error.value)


def test_fmusim_style_array_columns_in_input_tables_and_references(arrays3, tmp_path, capsys):
    """A cell holding an array's values separated by spaces, as fmusim and fmpy.util.write_csv write
    them: an input table column ``u`` = ``3 4`` drives u[1] and u[2]; an fmpy result written so is
    a reference `cosim compare` matches element by element, A's values by position onto A[i,j]."""
    table = tmp_path / "in.csv"
    table.write_text("time,u\n0,3 4\n1,3 4\n")
    assert main(["run", str(arrays3), "--input-file", str(table), "-o", str(tmp_path / "in.out.csv"), "-q"]) == 0
    driven = read(tmp_path / "in.out.csv")
    np.testing.assert_array_equal(driven["Arrays3.u[2]"], 4.0)
    np.testing.assert_array_equal(driven["y"], 43.0)
    table.write_text("time,u\n0,3 4 5\n1,3 4 5\n")
    assert main(["run", str(arrays3), "--input-file", str(table), "-o", str(tmp_path / "bad.csv"), "-q"]) == 2
    assert "the column 'u' holds 3 values per row; Arrays3.u is an array of 2 values" in capsys.readouterr().err

    reference = tmp_path / "fmpy.csv"
    fmpy.util.write_csv(str(reference), fmpy.simulate_fmu(str(arrays3), output_interval=0.25))
    assert "11 12 13 21 22 23" in reference.read_text()
    out = tmp_path / "o.csv"
    assert main(["run", str(arrays3), "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    assert main(["compare", str(reference), str(out), "--rtol", "0", "--atol", "0"]) == 0
    assert "21 of 21 signals within tolerance" in capsys.readouterr().out
    assert main(["compare", str(out), str(reference), "--signals", "A[*]", "outputs[*]", "--rtol", "0",
                 "--atol", "0"]) == 0
    assert "10 of 10 signals within tolerance" in capsys.readouterr().out


TICKS3 = _description("Ticks", "c10c0000-0000-4000-8000-000000000041", """\
    <Clock name="tick" valueReference="7" causality="output" intervalVariability="constant" intervalDecimal="0.5"/>
    <Float64 name="y" valueReference="8" causality="output" variability="continuous"/>
""", '<Output valueReference="7"/><Output valueReference="8"/>')


def test_a_single_fmus_clock_is_named_not_dropped(tmp_path, capsys):
    """`cosim run X.fmu` skipped a Clock output without a word at 5dbfe07; it is named now (fmpy
    does not record it either)."""
    fmu = build_c_fmu(tmp_path, "Ticks", TICKS3, "static void start(S *s) {}\n"
                      "static void calculate(S *s) { s->r[8] = s->time; }\n"
                      "static int step(S *s, double t, double h) { return 0; }\n", fmi="3.0")
    assert main(["run", str(fmu), "-o", str(tmp_path / "o.csv"), "-q"]) == 0
    warned = _warnings(capsys.readouterr().err)
    assert len(warned) == 1 and "neither exchanged nor recorded: Ticks.tick (Clock)" in warned[0], warned
    np.testing.assert_array_equal(read(tmp_path / "o.csv")["y"], [0, 0.25, 0.5, 0.75, 1])


#: an FMI 3.0 Model Exchange and Co-Simulation FMU with an array input and array states, as the
#: Reference FMUs' StateSpace: x' = u (x[1..2] from 0), y = x + u (explicit Euler as Co-Simulation)
INTEGRATOR3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Integrator3" instantiationToken="{a7a70000-0000-4000-8000-000000000042}">
  <ModelExchange modelIdentifier="Integrator3"/>
  <CoSimulation modelIdentifier="Integrator3" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01" tolerance="1e-10"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="u" valueReference="2" causality="input" variability="continuous" start="1 2">
      <Dimension start="2"/></Float64>
    <Float64 name="x" valueReference="0" causality="local" variability="continuous" initial="exact" start="0 0">
      <Dimension start="2"/></Float64>
    <Float64 name="der(x)" valueReference="8" causality="local" variability="continuous" derivative="0">
      <Dimension start="2"/></Float64>
    <Float64 name="y" valueReference="10" causality="output" variability="continuous">
      <Dimension start="2"/></Float64>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="10" dependencies="0 2"/>
    <ContinuousStateDerivative valueReference="8"/>
  </ModelStructure>
</fmiModelDescription>
"""
INTEGRATOR3_BODY = r"""
#define NX 2
#define NZ 0
static void start(S *s) {
    s->extent[2] = 2; s->extent[0] = 2; s->extent[8] = 2; s->extent[10] = 2; s->r[2] = 1; s->r[3] = 2; }
static void calculate(S *s) {
    for (int e = 0; e < 2; e++) { s->r[8 + e] = s->r[2 + e]; s->r[10 + e] = s->r[e] + s->r[2 + e]; } }
static int step(S *s, double t, double h) { for (int e = 0; e < 2; e++) s->r[e] += h * s->r[2 + e]; return 0; }
static void derivatives(S *s, double dx[]) { for (int e = 0; e < 2; e++) dx[e] = s->r[2 + e]; }
static void indicators(S *s, double z[]) {}
static void event(S *s) {}
"""


def test_a_model_exchange_fmu_with_an_array_input_is_integrated_as_fmpy_integrates_it(tmp_path):
    """FMI 3.0 Model Exchange with an array input (MapleSim's CoupledClutches ME, the Reference FMUs'
    StateSpace): the master reads the inputs' values to see them change, nValues being the number
    of values behind the value references (the test FMU refuses another count, as StateSpace does:
    the run failed 'Expected nValues >= 3 but was 1'); y = x + u with x' = u equals fmpy's ME run
    and the exact solution."""
    fmu = build_c_fmu(tmp_path, "Integrator3", INTEGRATOR3, INTEGRATOR3_BODY, "3.0", model_exchange=True)
    out = tmp_path / "me.csv"
    assert main(["run", str(fmu), "--fmi-type", "ModelExchange", "-o", str(out)]) == 0
    ours = read(out)
    theirs = fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", output_interval=0.01, relative_tolerance=1e-10)
    for e in (1, 2):
        np.testing.assert_allclose(ours[f"y[{e}]"], np.interp(ours["time"], theirs["time"], theirs["y"][:, e - 1]),
                                   atol=1e-6)
        np.testing.assert_allclose(ours[f"y[{e}]"], e * (1 + ours["time"]), atol=1e-6)
