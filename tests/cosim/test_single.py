"""`cosim run X.fmu` and the options of fmpy simulate (issue 30, item 1; `cosim.plan.prepare`, `cosim.read.single`,
`cosim.plan.inputs`): one FMU without an SSD, an input table (fmpy's format and interpolation rules),
start values, the output interval and the FMI type, checked against ``fmpy.simulate_fmu`` given
the same FMU, table and values, on a C FMU compiled here (tests/single_fmus.py)."""
from __future__ import annotations

import json

import fmpy
import numpy as np
import pytest
from fmpy.simulation import Input
from fmpy.util import read_csv

from cosim.cli import main
from cosim.read.inputs import read_input_table
from cosim.run.feed import interpolate
from cosim.record.results import read
from single_fmus import build_drive
from ssdgen import ssd_text, write_system

#: an event row (t = 1 twice: every input jumps), discrete inputs held between samples, a Real
#: interpolated between samples off the grid (0.25, 1.55); the discrete inputs change on the
#: grid (at 0.2, 1 and 1.5: fmpy adds a communication point at a change between two, see below)
TABLE = """time,u,d,k,b
0,0,0,0,0
0.2,0.8,0.5,1,1
0.25,1,0.5,1,1
1.0,1,2,3,1
1.0,-1,4,5,0
1.5,0.75,4,-2,1
1.55,0.5,4,-2,1
2,0.5,4,5,1
"""
#: discrete inputs changing between communication points (0.25, 1.55)
OFF_GRID = """time,u,d,k,b
0,0,0,0,0
0.25,1,0.5,1,1
1.0,1,2,3,1
1.0,-1,4,5,0
1.55,0.5,4,-2,1
2,0.5,4,5,1
"""
OUTPUTS = ["x", "y", "yk", "yb", "yd"]


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    return build_drive(tmp_path_factory.mktemp("drive"))


@pytest.fixture
def table(tmp_path):
    path = tmp_path / "Drive_in.csv"
    path.write_text(TABLE)
    return path


def run(tmp_path, *args) -> tuple[int, np.ndarray | None]:
    out = tmp_path / "out.csv"
    code = main(["run", *map(str, args), "-o", str(out), "-q"])
    return code, read(out) if code == 0 else None


def assert_same_as_fmpy(ours: np.ndarray, theirs: np.ndarray, component: str | None = "Drive") -> None:
    np.testing.assert_array_equal(ours["time"], theirs["time"])
    for name in OUTPUTS:
        np.testing.assert_array_equal(ours[f"{component}.{name}" if component else name].astype(float),
                                      theirs[name].astype(float),
                                      err_msg=name)


def test_an_fmu_with_an_input_table_runs_as_fmpy_runs_it(drive, table, tmp_path, capsys):
    """The default experiment (0..2 s, step 0.1), the table's Reals interpolated, the discrete
    inputs held, the event row taken from the right: every output bit for bit as fmpy's."""
    code, ours = run(tmp_path, drive, "--input-file", table)
    assert code == 0 and "warning" not in capsys.readouterr().err   # its events (0.2, 1, 1.5) are on the grid
    theirs = fmpy.simulate_fmu(str(drive), input=read_csv(str(table)), output_interval=0.1)
    assert len(ours) == 21 and ours["time"][-1] == 2.0
    assert_same_as_fmpy(ours, theirs)
    assert_same_as_fmpy(ours, theirs, component=None)   # each output also under fmpy's name
    at = {round(float(t), 6): i for i, t in enumerate(ours["time"])}
    assert ours["Drive.u"][at[0.1]] == pytest.approx(0.4)          # interpolated between 0 and 0.25
    assert ours["Drive.k"][at[0.1]] == 0 and ours["Drive.k"][at[0.2]] == 1 and ours["Drive.k"][at[0.9]] == 1
    assert ours["Drive.u"][at[1.0]] == -1 and ours["Drive.k"][at[1.0]] == 5  # the event's right value
    assert ours["Drive.k"][at[1.6]] == -2 and ours["Drive.yk"][at[1.7]] == -2
    meta = json.loads((tmp_path / "out.json").read_text())
    assert meta["step_size_source"] == "modelDescription.xml DefaultExperiment stepSize"
    assert meta["kernel"] == "native" and any("input table" in why for why in meta["python_operations"])


def test_discrete_changes_between_communication_points(tmp_path, capsys):
    """They take effect at the next communication point: as fmpy runs an FMU that cannot vary its
    step (bit for bit); one that can gets an extra communication point from fmpy, not from cosim."""
    table = tmp_path / "off.csv"
    table.write_text(OFF_GRID)
    fixed, variable = build_drive(tmp_path / "fixed", variable_step=False), build_drive(tmp_path / "variable")
    code, ours = run(tmp_path, fixed, "--input-file", table)
    assert code == 0
    assert "input events at t = 0.25, 1.55 s fall between communication points (step 0.1 s)" in \
        capsys.readouterr().err
    assert_same_as_fmpy(ours, fmpy.simulate_fmu(str(fixed), input=read_csv(str(table)), output_interval=0.1))
    assert ours["Drive.k"][3] == 1 and ours["Drive.k"][2] == 0   # the change at 0.25 seen at 0.3
    theirs = fmpy.simulate_fmu(str(variable), input=read_csv(str(table)), output_interval=0.1)
    assert 0.25 in theirs["time"] and 1.55 in theirs["time"] and len(theirs) == len(ours) + 2


def test_start_values_and_output_interval_as_fmpy(drive, table, tmp_path):
    code, ours = run(tmp_path, drive, "--input-file", table, "--start-value", "gain=3", "--start-value", "k=7",
                     "--output-interval", "0.05", "--stop-time", "1.5")
    assert code == 0
    theirs = fmpy.simulate_fmu(str(drive), input=read_csv(str(table)), output_interval=0.05, stop_time=1.5,
                               start_values={"gain": 3.0, "k": 7})
    assert len(ours) == 31
    assert_same_as_fmpy(ours, theirs)
    assert ours["Drive.y"][2] == pytest.approx(3 * ours["Drive.u"][1])
    meta = json.loads((tmp_path / "out.json").read_text())
    assert meta["parameter_origins"]["Drive.gain"].startswith("--start-value")


def test_simulate_fmu_in_python_as_fmpy(drive, table):
    import cosim

    ours = cosim.simulate_fmu(drive, input_file=table, start_values={"gain": 3, "b": True}, stop_time=1.0)
    theirs = fmpy.simulate_fmu(str(drive), input=read_csv(str(table)), output_interval=0.1, stop_time=1.0,
                               start_values={"gain": 3.0, "b": True})
    assert_same_as_fmpy(ours, theirs)
    assert ours["Drive.y"][-1] == 3 * ours["Drive.u"][-2]


def test_without_inputs_the_fmu_runs_its_default_experiment_on_the_compiled_kernel(drive, tmp_path):
    code, ours = run(tmp_path, drive, "--start-value", "u=1")
    assert code == 0
    theirs = fmpy.simulate_fmu(str(drive), output_interval=0.1, start_values={"u": 1.0})
    assert_same_as_fmpy(ours, theirs)
    assert ours["Drive.x"][-1] == pytest.approx(2.0)
    meta = json.loads((tmp_path / "out.json").read_text())
    assert meta["components"]["Drive"]["interface"] == "fmi2-cs" and meta["algorithm"] == "jacobi"


def test_without_a_default_experiment_the_grid_is_fmpys(tmp_path):
    """No DefaultExperiment: 1 s from 0 on fmpy's automatic interval (2 ms), as fmpy runs it."""
    fmu = build_drive(tmp_path, experiment=False)
    code, ours = run(tmp_path, fmu, "--start-value", "u=1")
    assert code == 0
    assert len(ours) == 501 and ours["time"][-1] == 1.0
    assert_same_as_fmpy(ours, fmpy.simulate_fmu(str(fmu), start_values={"u": 1.0}))
    assert json.loads((tmp_path / "out.json").read_text())["step_size_source"] == "fmpy's automatic interval"


def test_an_input_table_drives_a_system_by_component_and_input(drive, tmp_path, capsys):
    """In an SSP system the columns are ``component.input``: src's u from the table, dst's u
    connected from src's y, dst's k from the table; the same as a run of each FMU alone, and
    with every FMU in a process of its own (--isolate)."""
    folder = write_system(tmp_path / "sys", {"Drive.fmu": drive}, ssd_text(
        "pair", {"src": ("Drive.fmu", {"u": "input", "y": "output"}),
                 "dst": ("Drive.fmu", {"u": "input", "k": "input", "x": "output"})},
        [("src", "y", "dst", "u")], stop=1.0, step=0.1))
    (tmp_path / "in.csv").write_text("time,src.u,dst.k\n0,0,1\n0.5,1,1\n0.5,1,3\n1,2,3\n")
    code, ours = run(tmp_path, folder, "--input-file", tmp_path / "in.csv", "--start-value", "dst.gain=5")
    assert code == 0
    assert list(ours["dst.k"]) == [1] * 5 + [3] * 6
    meta = json.loads((tmp_path / "out.json").read_text())
    assert meta["parameters"]["dst.gain"] == 5.0 and meta["parameter_origins"]["dst.gain"].startswith("--start-value")
    np.testing.assert_array_equal(ours["dst.u"][1:], ours["src.y"][1:])
    single = fmpy.simulate_fmu(str(drive), input=read_csv(str(tmp_path / "in.csv")).astype(
        [("time", float), ("u", float), ("k", float)]), output_interval=0.1, stop_time=1.0)
    np.testing.assert_array_equal(ours["src.y"], single["y"])
    # the table's value at t reaches dst through src's y one communication point later, as fmpy records y
    assert ours["src.y"][3] == 2 * ours["src.u"][2]

    for column, words in (("dst.u", "driven by a connection"), ("src.k", "no connector of component 'src'"),
                          ("src.q", "no input of that name")):
        (tmp_path / "bad.csv").write_text(f"time,{column}\n0,1\n")
        assert main(["run", str(folder), "--input-file", str(tmp_path / "bad.csv"), "-o", str(tmp_path / "b.csv"),
                     "-q"]) == 2
        assert words in capsys.readouterr().err

    code, isolated = run(tmp_path, folder, "--input-file", tmp_path / "in.csv", "--start-value", "dst.gain=5",
                         "--isolate")
    assert code == 0 and all(np.array_equal(isolated[n], ours[n]) for n in ours.dtype.names)


@pytest.mark.parametrize("text, words", [
    ("time,u,speed\n0,1,2\n", ["bad.csv", "column 'speed'", "no input of that name in Drive"]),
    ("time,u\n0,1\n1,2\n0.5,3\n", ["bad.csv", "line 4, column 'time'", "before the time of the row before"]),
    ("time,u,k\n0,1,2\n1,x,2\n", ["bad.csv", "line 3, column 'u'", "'x' is not a finite number"]),
    ("time,u,k\n0,1,2\n1,1,2.5\n", ["bad.csv", "line 3, column 'k'", "Integer input"]),
    ("time,u,b\n0,1,2\n", ["bad.csv", "line 2, column 'b'", "Boolean input"]),
    ("t,u\n0,1\n", ["bad.csv", "line 1, column 1", "first column is 't'"]),
    ("time,u,u\n0,1,1\n", ["bad.csv", "column 'u' is given twice"]),
    ("time,u\n0,1,2\n", ["bad.csv", "line 2", "3 cells"]),
    ("time,u\n0,nan\n", ["bad.csv", "'nan' is not a finite number"]),
])
def test_a_wrong_input_table_is_refused_naming_file_column_and_line(drive, tmp_path, capsys, text, words):
    (tmp_path / "bad.csv").write_text(text)
    assert main(["run", str(drive), "--input-file", str(tmp_path / "bad.csv"), "-o", str(tmp_path / "o.csv"),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err
    assert "Traceback" not in err and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("args, words", [
    (["--start-value", "gian=3"], ["no variable 'gian'", "gain"]),
    (["--start-value", "gain=abc"], ["'abc' is not a Real"]),
    (["--start-value", "k=1.5"], ["--start", "k"]),
    (["--start-value", "x=1"], ["x"]),
    (["--start-value", "gain"], ["not NAME=VALUE"]),
    (["--fmi-type", "ModelExchange"], ["no Model Exchange interface"]),
    (["--output-interval", "0.1", "--step", "0.2"], ["--output-interval", "give one"]),
])
def test_wrong_start_values_and_options_are_refused(drive, tmp_path, capsys, args, words):
    assert main(["run", str(drive), *args, "-o", str(tmp_path / "o.csv"), "-q"]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err


def test_an_fmu_that_cannot_run_is_refused_naming_it(drive, tmp_path, capsys):
    import zipfile

    broken = tmp_path / "NoBinary.fmu"
    with zipfile.ZipFile(drive) as source, zipfile.ZipFile(broken, "w") as target:
        for member in source.namelist():
            if not member.startswith("binaries/"):
                target.writestr(member, source.read(member))
    assert main(["validate", str(broken)]) == 2
    err = capsys.readouterr().err
    assert f"{broken}, the FMU given: NoBinary.fmu has no binary for this platform" in err, err
    assert main(["run", str(tmp_path / "Missing.fmu"), "-q"]) == 2
    assert "Missing.fmu" in capsys.readouterr().err


def test_validate_and_info_of_an_fmu(drive, capsys):
    assert main(["validate", str(drive)]) == 0
    assert "valid — 1 FMU, 0 connections" in capsys.readouterr().out
    assert main(["info", str(drive)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Drive.fmu: Drive, FMI 2.0 fmi2-cs")   # issue 45: the FMU's own variables, any FMU
    rows = {line.split()[0]: line.split()[1] for line in out.splitlines() if line.startswith("  ")}
    assert rows["k"] == "Integer" and rows["y"] == "Real" and "parameters (1):" in out
    assert main(["pack", str(drive), "-o", "x.ssp"]) == 2


def test_booleans_may_be_written_true_and_false(tmp_path):
    (tmp_path / "a.csv").write_text("time,b\n0,true\n1,False\n")
    (tmp_path / "b.csv").write_text("time,b\n0,1\n1,0\n")
    a, b = read_input_table(tmp_path / "a.csv"), read_input_table(tmp_path / "b.csv")
    np.testing.assert_array_equal(a.values, b.values)
    assert a.lines == [2, 3]


def test_interpolation_is_fmpys():
    """`cosim.plan.inputs.interpolate` against ``fmpy.simulation.Input.interpolate`` at sample times,
    between them, at the event, before and after the table, left and right."""
    t = np.array([0.0, 0.25, 1.0, 1.0, 1.55, 2.0])
    table = np.array([[0.0, 1.0, 1.0, -1.0, 0.5, 0.5], [0.0, 1.0, 3.0, 5.0, -2.0, 5.0]])
    for time in [-1.0, 0.0, 0.1, 0.25, 0.6, 1.0 - 1e-12, 1.0, 1.0 + 1e-13, 1.2, 1.55, 2.0, 3.0]:
        for discrete in (False, True):
            for after in (False, True):
                expected, _ = Input.interpolate(time, t, table, discrete=discrete, after_event=after)
                np.testing.assert_array_equal(interpolate(time, t, table, discrete, after), expected)


LIFT = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Lift" instantiationToken="{9e0c0000-0000-4000-8000-000000003001}">
  <ModelExchange modelIdentifier="Lift"/>
  <CoSimulation modelIdentifier="Lift"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01" tolerance="1e-10"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="h" valueReference="0" causality="output" variability="continuous" initial="exact" start="1"/>
    <Float64 name="der(h)" valueReference="8" causality="local" variability="continuous" derivative="0"/>
    <Float64 name="v" valueReference="1" causality="output" variability="continuous" initial="exact" start="0"/>
    <Float64 name="der(v)" valueReference="9" causality="local" variability="continuous" derivative="1"/>
    <Float64 name="lift" valueReference="7" causality="input" variability="continuous" start="0"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="0" dependencies=""/><Output valueReference="1" dependencies=""/>
    <ContinuousStateDerivative valueReference="8"/><ContinuousStateDerivative valueReference="9"/>
  </ModelStructure>
</fmiModelDescription>
"""
#: h' = v, v' = lift − 9.81; as Co-Simulation, explicit Euler over the communication step
LIFT_BODY = """
#define NX 2
#define NZ 0
static void start(S *s) { s->r[0] = 1.0; s->r[1] = 0.0; }
static void calculate(S *s) { s->r[8] = s->r[1]; s->r[9] = s->r[7] - 9.81; }
static int step(S *s, double t, double h) { s->r[0] += h * s->r[1]; s->r[1] += h * (s->r[7] - 9.81); return 0; }
static void derivatives(S *s, double dx[]) { dx[0] = s->r[1]; dx[1] = s->r[7] - 9.81; }
static void indicators(S *s, double z[]) {}
static void event(S *s) {}
"""


def test_fmi_type_picks_the_interface_of_an_fmu_that_has_both(tmp_path):
    """--fmi-type ModelExchange integrates the FMU in the master; a piecewise-constant lift from
    the table (its jumps on the grid) gives fmpy's ModelExchange result to its solver's tolerance."""
    from cfmus import build_c_fmu

    fmu = build_c_fmu(tmp_path, "Lift", LIFT, LIFT_BODY, "3.0", model_exchange=True)
    table = tmp_path / "lift.csv"
    table.write_text("time,lift\n0,0\n0.5,0\n0.5,20\n1,20\n")
    code, cs = run(tmp_path, fmu, "--input-file", table)
    assert code == 0 and json.loads((tmp_path / "out.json").read_text())["components"]["Lift"]["interface"] == "fmi3-cs"
    code, me = run(tmp_path, fmu, "--input-file", table, "--fmi-type", "ModelExchange")
    assert code == 0 and json.loads((tmp_path / "out.json").read_text())["components"]["Lift"]["interface"] == "fmi3-me"
    theirs = fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", input=read_csv(str(table)), output_interval=0.01,
                               relative_tolerance=1e-10)
    ref = np.interp(me["time"], theirs["time"], theirs["h"])
    np.testing.assert_allclose(me["Lift.h"], ref, atol=1e-6)
    exact = np.where(me["time"] <= 0.5, 1 - 9.81 / 2 * me["time"] ** 2,
                     1 - 9.81 / 8 - 9.81 / 2 * (me["time"] - 0.5) + 10.19 / 2 * (me["time"] - 0.5) ** 2)
    np.testing.assert_allclose(me["Lift.h"], exact, atol=1e-6)
    assert abs(cs["Lift.h"][-1] - me["Lift.h"][-1]) > 5e-4     # Euler over 0.01 s steps is not the ODE


SYSTEM_INPUT = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0" name="driven">
  <ssd:System name="root">
    <ssd:Connectors><ssd:Connector name="r" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors>
    <ssd:Elements>
      <ssd:Component name="a" source="resources/Drive.fmu"><ssd:Connectors>
        <ssd:Connector name="u" kind="input"/><ssd:Connector name="d" kind="input"/></ssd:Connectors></ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startConnector="r" endElement="a" endConnector="u">
        <ssc:LinearTransformation factor="2" offset="1"/></ssd:Connection>
      <ssd:Connection startConnector="r" endElement="a" endConnector="d"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
"""


def test_an_input_table_drives_a_system_input_connector(drive, tmp_path, capsys):
    """A column naming an undriven input connector of the root system drives what it feeds,
    through each connection's LinearTransformation (a.u = 2 r + 1, a.d = r), each by its own rule."""
    folder = write_system(tmp_path / "sys", {"Drive.fmu": drive}, SYSTEM_INPUT)
    assert main(["info", str(folder), "--fmi-type", "CoSimulation"]) == 2   # a system's SSD chooses
    assert "implementation attribute" in capsys.readouterr().err
    (tmp_path / "in.csv").write_text("time,r\n0,0\n1,1\n")
    code, ours = run(tmp_path, folder, "--input-file", tmp_path / "in.csv", "--step", "0.1")
    assert code == 0
    r = np.clip(ours["time"], 0, 1)
    np.testing.assert_allclose(ours["a.u"], 2 * r + 1, rtol=0, atol=1e-15)
    assert list(ours["a.d"]) == [0.0] * 10 + [1.0]     # a discrete Real: the sample at 0 held until 1
    # without the table, the connector has no value: refused, as before
    assert main(["run", str(folder), "--step", "0.1", "-o", str(tmp_path / "n.csv"), "-q"]) == 2
    assert "system connector 'r'" in capsys.readouterr().err


def test_a_cross_check_case_passes_the_fmi_cross_check_rule(drive, tmp_path):
    """An FMI cross-check case (FMU, ``_in.csv``, ``_ref.csv``, ``_ref.opt``) run as the cross-check
    tools run it: ``--input-file``, the ``.opt``'s StopTime and StepSize; the result within the
    cross-check band of the reference (``fmpy.util.validate_result``: no sample outside it), and
    outside it when a start value differs."""
    from fmpy.util import read_ref_opt_file, validate_result, write_csv

    case = tmp_path / "case"
    case.mkdir()
    (case / "Drive_in.csv").write_text(TABLE)
    (case / "Drive_ref.opt").write_text("StartTime,0.0\nStopTime,2.0\nStepSize,0.1\nRelTol,0.0001\n")
    ref = fmpy.simulate_fmu(str(drive), input=read_csv(str(case / "Drive_in.csv")), output_interval=0.1)
    write_csv(str(case / "Drive_ref.csv"), ref.astype([(n, float) for n in ref.dtype.names]))  # fmpy reads numbers
    opts = read_ref_opt_file(str(case / "Drive_ref.opt"))
    reference = read_csv(str(case / "Drive_ref.csv"))

    def outliers(*extra) -> float:
        code, ours = run(tmp_path, drive, "--input-file", case / "Drive_in.csv", "--stop", opts["StopTime"],
                         "--output-interval", opts["StepSize"], *extra)
        assert code == 0
        return validate_result(ours, reference, stop_time=opts["StopTime"])

    assert outliers() == 0
    assert outliers("--start-value", "gain=2.5") > 0
    run(tmp_path, drive, "--input-file", case / "Drive_in.csv", "--stop", opts["StopTime"])
    assert main(["compare", str(case / "Drive_ref.csv"), str(tmp_path / "out.csv"), "--rtol", "0", "--atol", "0"]) == 0
