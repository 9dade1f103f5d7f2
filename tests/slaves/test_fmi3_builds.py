"""Issue 41: every FMU of ours also as FMI 3.0 Co-Simulation (``<Name>3.fmu``, greyfmu.fmi3), the
same model as its FMI 2.0 sibling, behind greyfmu's FMI 3.0 loader (greyfmu/loader/fmi3_loader.c).

- Same numbers: each pair run alone in cosim over the FMI 2.0 FMU's DefaultExperiment with a
  representative input (tests/fmi3_pairs.py) agrees to 1e-12 (`PAIRS` by default; all 26 with
  GREYFMU_FMI3_ALL=1, whose figures are in the issue's closing note: 0.0 for every FMU);
- fmpy validates it without a message and simulates it; rebuilding gives the same bytes of
  modelDescription.xml and the same instantiation token;
- a C host without Python (tests/hostile_host3.c, compiled here) gets fmi3Error and one log line
  for every misuse FMI 3.0's calling sequence allows, never a crash;
- a Python exception is fmi3Error with one line of category logPythonException, and the instance
  lives on (fmi3Reset); FMU states get, set, serialise and restore as in FMI 2.0;
- under Debian's python3 (static libpython) it runs as its FMI 2.0 sibling does.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from dropinhost import environment
from fmi3_pairs import max_difference
from greyfmu.build import build_fmus, fmu_names

PAIRS = ["PID", "Step", "SOPDTPredictive", "BoilerTurbine", "GainScheduledPID"]
"""The pairs compared in the default run: a controller with Enumerations, a source, a controller
with a tunable parameter and warnings, a MIMO plant with units, a gain-scheduled controller."""
ALL = fmu_names() if os.environ.get("GREYFMU_FMI3_ALL") == "1" else PAIRS
HOST_SOURCE = Path(__file__).resolve().parents[1] / "hostile_host3.c"
OK, DISCARD, ERROR = 0, 2, 3


@pytest.fixture(scope="module")
def fmi3_fmus(tmp_path_factory) -> dict[str, Path]:
    """The FMI 3.0 FMUs of `ALL` and their FMI 2.0 siblings, built into one folder (about 2 s each)."""
    folder = tmp_path_factory.mktemp("fmi3")
    names = [name for base in ALL for name in (base, base + "3")]
    return {path.stem: path for path in build_fmus(names, out_dir=folder)}


@pytest.mark.parametrize("name", ALL)
def test_the_fmi3_fmu_computes_what_its_fmi2_sibling_computes_in_cosim(fmi3_fmus, name, tmp_path):
    difference, samples, outputs = max_difference(fmi3_fmus[name], fmi3_fmus[name + "3"], tmp_path)
    assert difference <= 1e-12 and samples > 100 and outputs >= 1


@pytest.mark.parametrize("name", ALL)
def test_the_fmi3_fmu_validates_and_simulates_in_fmpy(fmi3_fmus, name):
    fmu = fmi3_fmus[name + "3"]
    assert validate_fmu(str(fmu)) == []
    description = read_model_description(str(fmu))
    assert (description.fmiVersion, description.coSimulation.modelIdentifier) == ("3.0", name + "3")
    assert [v.name for v in description.modelVariables if v.causality == "independent"] == ["time"]
    result = fmpy.simulate_fmu(str(fmu))
    assert len(result) > 100 and all(np.all(np.isfinite(result[column])) for column in result.dtype.names)


def test_the_fmi3_fmu_is_the_fmi2_fmus_model_with_fmi3_types(fmi3_fmus):
    """PID3's variables are PID's (names, value references, units, starts, descriptions), its mode
    parameters FMI 3.0 Enumerations of described types, and it documents itself."""
    two = {v.name: v for v in read_model_description(str(fmi3_fmus["PID"])).modelVariables}
    three = read_model_description(str(fmi3_fmus["PID3"]))
    by_name = {v.name: v for v in three.modelVariables if v.name != "time"}
    assert set(by_name) == set(two)
    for name, variable in by_name.items():
        other = two[name]
        assert (variable.valueReference, variable.causality, variable.variability, variable.start,
                variable.description, variable.unit) == (other.valueReference, other.causality, other.variability,
                                                         other.start, other.description, other.unit), name
    assert {name: v.type for name, v in by_name.items() if v.type != "Float64"} == {
        "anti_windup": "Enumeration", "derivative_on": "Enumeration", "form": "Enumeration",
        "integral_mode": "Enumeration"}
    items = {t.name: [(i.name, i.value) for i in t.items] for t in three.typeDefinitions}
    assert items["IntegralMode"] == [("METHOD1", "1"), ("METHOD2", "2"), ("METHOD3", "3")]
    with zipfile.ZipFile(fmi3_fmus["PID3"]) as archive:
        page = archive.read("documentation/index.html").decode()
        names = set(archive.namelist())
    assert "FMI 3.0 Co-Simulation FMU" in page and three.instantiationToken in page
    assert {"binaries/x86_64-linux/PID3.so", "binaries/x86_64-linux/pythonfmu3-export.so",
            "binaries/x86_64-linux/greyfmu-process.so"} <= names


def test_rebuilding_gives_the_same_model_description_and_token(fmi3_fmus, tmp_path):
    (again,) = build_fmus(["PID3"], out_dir=tmp_path, force=True)
    with zipfile.ZipFile(fmi3_fmus["PID3"]) as first, zipfile.ZipFile(again) as second:
        assert first.read("modelDescription.xml") == second.read("modelDescription.xml")
    token = read_model_description(str(again)).instantiationToken
    assert token != read_model_description(str(fmi3_fmus["PID"])).guid


def test_greyfmu_build_fmi_3_names_the_fmi3_set(monkeypatch, tmp_path, capsys):
    """``greyfmu build --fmi 3`` asks for <Name>3 of every FMU (the builds themselves are the tests' above)."""
    from greyfmu import cli

    asked = []
    monkeypatch.setattr(cli, "build_fmus", lambda names, out, force, echo: asked.append(names) or [])
    assert cli.main(["build", "--fmi", "3", "--out", str(tmp_path)]) == 0
    assert asked == [[name + "3" for name in fmu_names()]]


# ---- a C host without Python, FMI 3.0's calling sequence ----

# case: (expected result, a text its one log line holds)
REFUSED = {
    "resource_missing": ("null", "which does not exist"),
    "token_wrong": ("null", "instantiationToken '{%s%n-not-the-token}' is not this FMU's"),
    "token_null": ("null", "instantiationToken NULL is not this FMU's"),
    "model_exchange": ("null", "fmi3InstantiateModelExchange: this FMU is Co-Simulation only"),
    "event_mode_used": ("null", "eventModeUsed = true, but this FMU has no event mode"),
    "intermediate_variables": ("null", "nRequiredIntermediateVariables = 1, but this FMU provides no intermediate"),
    "name_null": ("null", "fmi3InstantiateCoSimulation: instanceName is NULL"),
    "step_before_init": (ERROR, "fmi3DoStep: not allowed in this state (allowed in: stepMode) (instance 'hostile', "
                                "state instantiated)"),
    "step_in_initialization_mode": (ERROR, "fmi3DoStep: not allowed in this state (allowed in: stepMode) "
                                           "(instance 'hostile', state initializationMode)"),
    "step_after_terminate": (ERROR, "(instance 'hostile', state terminated)"),
    "exit_without_enter": (ERROR, "fmi3ExitInitializationMode: not allowed in this state"),
    "enter_twice": (ERROR, "fmi3EnterInitializationMode: not allowed in this state (allowed in: instantiated)"),
    "get_before_init": (ERROR, "fmi3GetFloat64: not allowed in this state"),
    "terminate_before_init": (ERROR, "fmi3Terminate: not allowed in this state (allowed in: stepMode, stepDiscarded)"),
    "enter_event_mode": (ERROR, "fmi3EnterEventMode: this FMU is Co-Simulation only, without event mode"),
    "null_value_array": (ERROR, "fmi3GetFloat64: the value array is NULL with nvr = 1"),
    "null_vr_array": (ERROR, "fmi3GetFloat64: the value reference array vr is NULL with nvr = 1"),
    "values_count": (ERROR, "fmi3GetFloat64: nValues = 4, but the 1 variables named hold 1 values"),
    "unknown_vr": (ERROR, "fmi3GetFloat64: vr[0] = 999999 is not a value reference of this FMU"),
    "wrong_type_vr": (ERROR, "a Float64 variable, not of type Int32"),
    "no_such_type": (ERROR, "a Float64 variable: this FMU has no Float32 variables"),
    "set_time": (ERROR, "time is a continuous independent: after initialisation only inputs"),
    "step_huge": (ERROR, "fmi3DoStep: communicationStepSize = 1e+300 s is longer than this FMU's longest step"),
    "step_negative": (ERROR, "fmi3DoStep: communicationStepSize = -1: a step must be finite and > 0"),
    "step_zero": (ERROR, "fmi3DoStep: communicationStepSize = 0: a step must be finite and > 0"),
    "step_nan": (ERROR, "fmi3DoStep: communicationStepSize = nan: a step must be finite and > 0"),
    "time_nan": (ERROR, "fmi3DoStep: currentCommunicationPoint = nan is not finite"),
    "step_null_outputs": (ERROR, "fmi3DoStep: earlyReturn is NULL (FMI 3.0 requires each output argument)"),
    "step_not_from_the_last_end": (ERROR, "fmi3DoStep: currentCommunicationPoint = 5 s, but the instance is at "
                                          "0.10000000000000001 s"),
    "step_past_stop_time": (ERROR, "fmi3DoStep: the step [1, 1.5] s ends after stopTime = 1 s"),
    "null_fmu_state": (ERROR, "fmi3GetFMUState: FMUState (the fmi3FMUState* to fill) is NULL"),
    "format_guard": (ERROR, "(instance '%s%n%s%n', state instantiated)"),
}
HOSTILE = ["PID", "Step", "BoilerTurbine"]
"""FMUs with inputs and fixed Float64 parameters (PID, BoilerTurbine) and without inputs (Step)."""


def host3_arguments(fmu: Path, folder: Path) -> tuple[list[str], dict]:
    """hostile_host3's arguments after the folder for ``fmu`` extracted into ``folder``, and what the
    FMU has (a fixed Float64 parameter, an input)."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    description = read_model_description(str(folder))
    variables = description.modelVariables
    real = next(v for v in variables if v.causality == "output")
    fixed = next((v for v in variables if v.causality == "parameter" and v.type == "Float64"), None)
    inputs = [v for v in variables if v.causality == "input"]
    time = next(v for v in variables if v.causality == "independent")
    arguments = [description.coSimulation.modelIdentifier, description.instantiationToken, str(real.valueReference),
                 str(fixed.valueReference) if fixed else "-", str(inputs[0].valueReference) if inputs else "-",
                 str(time.valueReference)]
    return arguments, {"fixed": fixed is not None, "input": bool(inputs)}


def parse_host3(done: subprocess.CompletedProcess, has: dict) -> dict:
    """The results and log lines hostile_host3 printed (it must have ended by itself)."""
    assert done.returncode == 0 and done.stdout.rstrip().endswith("done"), \
        f"the host crashed ({done.returncode}):\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    results, logs = {}, {}
    for line in done.stdout.splitlines():
        if line.startswith("result "):
            _, case, value = line.split(" ", 2)
            results[case] = value
        elif line.startswith("log "):
            _, case, status, category, message = line.split(" ", 4)
            logs.setdefault(case, []).append((int(status), category, message))
    return {"results": results, "logs": logs, "stderr": done.stderr, **has}


def compile_host3(folder: Path) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (cc or gcc) on PATH to build tests/hostile_host3.c")
    host = folder / "hostile_host3"
    subprocess.run([compiler, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOST_SOURCE), "-ldl"], check=True)
    return host


def run_host3(host: Path, fmu: Path, folder: Path) -> dict:
    """hostile_host3 on ``fmu`` in a host without Python (no PYTHONPATH/PYTHONHOME: the FMU finds
    the interpreter that built it)."""
    arguments, has = host3_arguments(fmu, folder)
    done = subprocess.run([str(host), str(folder), *arguments], capture_output=True, text=True, timeout=300,
                          env=environment())
    return parse_host3(done, has)


@pytest.fixture(scope="module")
def hostile_runs(fmi3_fmus, tmp_path_factory) -> dict[str, dict]:
    folder = tmp_path_factory.mktemp("hostile3")
    host = compile_host3(folder)
    return {name: run_host3(host, fmi3_fmus[name + "3"], folder / name) for name in HOSTILE if name in ALL}


@pytest.mark.parametrize("name", [n for n in HOSTILE if n in ALL])
def test_every_fmi3_misuse_is_refused_with_one_log_line(hostile_runs, name):
    run = hostile_runs[name]
    failures = []
    for case, (expected, text) in REFUSED.items():
        lines = run["logs"].get(case, [])
        if run["results"][case] != str(expected):
            failures.append(f"{case}: returned {run['results'][case]}, expected {expected}")
        elif len(lines) != 1 or text not in lines[0][2] or lines[0][:2] != (ERROR, "logStatusError"):
            failures.append(f"{case}: log lines {lines}, expected one error line holding {text!r}")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("name", [n for n in HOSTILE if n in ALL])
def test_what_an_fmi3_host_may_do_works(hostile_runs, name):
    run = hostile_runs[name]
    results = run["results"]
    for case in ("resource_null", "resource_empty", "resource_plain_path", "resource_trailing_separator"):
        assert (results[case], results[f"{case}_step"]) == ("instance", str(OK)), case
    assert run["logs"]["resource_null"] == [(1, "logStatusWarning", "fmi3InstantiateCoSimulation: resourcePath is "
                                                                     "NULL or empty: using the FMU's own resources folder")]
    assert [results[case] for case in ("error_state_enter", "error_state_get", "error_state_reset",
                                       "error_state_step_after_reset")] == [str(ERROR), str(OK), str(OK), str(OK)]
    assert (results["unknown_vr_then_get"], results["empty_arrays"], results["step_to_stop_time"]) == (str(OK),) * 3
    # pythonfmu3 writes none of eventHandlingNeeded, earlyReturn: the loader does
    assert (results["step_outputs_written"], results["step_outputs"]) == (str(OK), "0 0 0 0.10000000000000001")
    # the start time reaches the slave through `time` (pythonfmu3 drops it)
    assert (results["start_time"], results["start_time_value"], results["start_time_step"]) == (str(OK), "7.5", str(OK))
    # no logger: the instance works, the guard's lines go to stderr
    assert (results["logger_null"], results["logger_null_step"]) == ("instance", str(ERROR))
    assert "greyfmu: hostile: fmi3DoStep: not allowed in this state" in run["stderr"]
    assert run["stderr"].count("greyfmu: fmi3DoStep: the instance (fmi3Instance) is NULL") == 1
    if run["fixed"]:
        assert (results["set_fixed_after_init"], results["set_fixed_unchanged"]) == (str(ERROR), "1")
    if run["input"]:  # the slave's own message, naming the instance %s%n%s%n, as data
        assert results["format_slave"] == str(DISCARD)
        ((status, _, message),) = run["logs"]["format_slave"]
        assert status == ERROR and message.startswith("%s%n%s%n: input ") and "is not a finite number" in message


# ---- the FMU's Python under the FMI 3.0 loader ----

class Lines(list):
    """The FMU's log lines (status, category, message)."""

    def __call__(self, environment, status, category, message):
        self.append((status, category.decode(), message.decode()))


def _instance(fmu: Path, folder: Path, lines: Lines) -> tuple[FMU3Slave, dict[str, int]]:
    description = read_model_description(str(fmu))
    slave = FMU3Slave(guid=description.instantiationToken, unzipDirectory=fmpy.extract(str(fmu), str(folder)),
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="pid3")
    slave.instantiate(loggingOn=False, logMessage=lines)
    return slave, {v.name: v.valueReference for v in description.modelVariables}


def test_a_python_exception_is_fmi3error_with_one_line_and_the_instance_lives_on(fmi3_fmus, tmp_path):
    """Ts = 0 makes the PID refuse its parameters in fmi3ExitInitializationMode: fmi3Error (pythonfmu3
    answers fmi3Fatal), one line naming the FMI 3.0 function; fmi3Reset, then a valid run."""
    from fmpy.fmi1 import FMICallException

    lines = Lines()
    slave, vr = _instance(fmi3_fmus["PID3"], tmp_path / "pid3", lines)
    try:
        slave.setFloat64([vr["Ts"]], [0.0])
        slave.enterInitializationMode(startTime=0.0)
        with pytest.raises(FMICallException) as raised:
            slave.exitInitializationMode()
        assert raised.value.status == ERROR
        errors = [line for line in lines if line[0] >= ERROR]
        assert len(errors) == 1 and errors[0][1] == "logPythonException"
        assert "pid3: fmi3ExitInitializationMode: ValueError: invalid parameters:" in errors[0][2]
        slave.reset()
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        slave.setFloat64([vr["r"]], [1.0])
        slave.doStep(0.0, 0.1)
        assert slave.getFloat64([vr["u"]])[0] > 0
    finally:
        slave.freeInstance()


def test_fmu_states_get_set_serialise_and_restore(fmi3_fmus, tmp_path):
    """A state taken at t = 1 s, restored after 2 s more, and restored from its serialised bytes in a
    second instance, replays the same outputs bit for bit (FMI 3.0 §2.2.9)."""
    lines = Lines()
    slave, vr = _instance(fmi3_fmus["PID3"], tmp_path / "a", lines)
    other, _ = _instance(fmi3_fmus["PID3"], tmp_path / "b", lines)
    try:
        for instance in (slave, other):
            instance.enterInitializationMode(startTime=0.0)
            instance.exitInitializationMode()
        slave.setFloat64([vr["r"]], [1.0])
        t = 0.0
        for _ in range(10):
            slave.doStep(t, 0.1)
            t += 0.1
        state = slave.getFMUState()
        data = slave.serializeFMUState(state)

        def replay(instance):
            instance.setFloat64([vr["y"]], [0.25])
            outputs, now = [], t
            for _ in range(20):
                instance.doStep(now, 0.1)
                now += 0.1
                outputs.append(instance.getFloat64([vr["u"], vr["e"]]))
            return outputs

        first = replay(slave)
        slave.setFMUState(state)
        assert replay(slave) == first
        restored = other.deserializeFMUState(data)
        other.setFMUState(restored)
        assert replay(other) == first
        slave.freeFMUState(state)
        other.freeFMUState(restored)
    finally:
        slave.freeInstance()
        other.freeInstance()
    assert [line for line in lines if line[0] >= ERROR] == []


UNDER_DEBIAN = '''
import sys, fmpy, numpy
result = fmpy.simulate_fmu(sys.argv[1], start_values={"y": 0.5}, stop_time=10.0)
print("u", repr(float(result["u"][-1])))
'''


def test_the_fmi3_fmu_runs_under_debians_static_python(fmi3_fmus, debian_python, tmp_path):
    """Debian's /usr/bin/python3 links libpython statically: the loader uses the host's Python as the
    FMI 2.0 loader does (tests/slaves/test_pythons.py), and the numbers are this Python's."""
    runs = {}
    for label, python in (("debian", debian_python), ("here", Path(sys.executable))):
        done = subprocess.run([str(python), "-c", UNDER_DEBIAN, str(fmi3_fmus["PID3"])], capture_output=True,
                              text=True, timeout=300, cwd=tmp_path, env=environment())
        assert done.returncode == 0, f"{label}: {done.stderr[-3000:]}"
        runs[label] = done.stdout
    assert runs["debian"] == runs["here"] and runs["here"].startswith("u ")
