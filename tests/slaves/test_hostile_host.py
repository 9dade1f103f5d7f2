"""Issue 25: a host can misuse our FMUs and get an error, never a crash.

tests/hostile_host.c (compiled here with the system compiler) dlopens an FMU's linux64 binary and
runs every misuse case on a fresh instance: resource locations in every RFC 8089 form, a missing
or remote one, a wrong GUID, Model Exchange, NULL callbacks, logger, instance and arrays, calls in
the wrong state, unknown value references, bad step sizes, a fixed parameter set after
initialisation, and log messages holding printf directives (the host's logger formats what it
gets, as a plain C host does).  The guard in greyfmu/loader/guard.h answers each with fmi2Error
(NULL from fmi2Instantiate) and one log line naming the call, the argument and the state.
"""
from __future__ import annotations

import re
import shutil
import sys
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from dropinhost import environment, unzip
from fmpy import read_model_description
from greyfmu.build import fmu_names

HOST_SOURCE = Path(__file__).resolve().parents[1] / "hostile_host.c"
OK, DISCARD, ERROR = 0, 2, 3

# case: (expected result, a text its one log line holds); None: no log line
REFUSED = {
    "resource_missing": ("null", "which does not exist"),
    "resource_other_host": ("null", "names the host 'elsewhere': only local files"),
    "resource_http": ("null", "is a 'http:' URI"),
    "resource_bad_percent": ("null", "not a valid percent-encoded byte"),
    "guid_wrong": ("null", "fmuGUID '{%s%n-not-the-guid}' is not this FMU's GUID"),
    "guid_null": ("null", "fmuGUID NULL is not this FMU's GUID"),
    "model_exchange": ("null", "fmuType = 0: this FMU is Co-Simulation only"),
    "name_null": ("null", "fmi2Instantiate: instanceName is NULL"),
    "step_before_init": (ERROR, "fmi2DoStep: not allowed in this state (allowed in: stepComplete) (instance 'hostile', "
                                "state instantiated)"),
    "step_in_initialization_mode": (ERROR, "fmi2DoStep: not allowed in this state (allowed in: stepComplete) "
                                           "(instance 'hostile', state initializationMode)"),
    "step_after_terminate": (ERROR, "fmi2DoStep: not allowed in this state (allowed in: stepComplete) "
                                    "(instance 'hostile', state terminated)"),
    "exit_without_enter": (ERROR, "fmi2ExitInitializationMode: not allowed in this state (allowed in: "
                                  "initializationMode) (instance 'hostile', state instantiated)"),
    "enter_twice": (ERROR, "fmi2EnterInitializationMode: not allowed in this state (allowed in: instantiated) "
                           "(instance 'hostile', state initializationMode)"),
    "setup_after_init": (ERROR, "fmi2SetupExperiment: not allowed in this state (allowed in: instantiated) "
                                "(instance 'hostile', state stepComplete)"),
    "get_before_init": (ERROR, "fmi2GetReal: not allowed in this state"),
    "terminate_before_init": (ERROR, "fmi2Terminate: not allowed in this state (allowed in: stepComplete, "
                                     "stepFailed) (instance 'hostile', state instantiated)"),
    "cancel_step": (ERROR, "fmi2CancelStep: not allowed: no step is ever in progress"),
    "null_value_array": (ERROR, "fmi2GetReal: the value array is NULL with nvr = 1 (instance 'hostile', state "
                                "stepComplete)"),
    "null_vr_array": (ERROR, "fmi2GetReal: the value reference array vr is NULL with nvr = 1"),
    "null_set_array": (ERROR, "fmi2SetReal: the value array is NULL with nvr = 1 (instance 'hostile', state "
                              "instantiated)"),
    "unknown_vr": (ERROR, "fmi2GetReal: vr[0] = 999999 is not a value reference of this FMU"),
    "wrong_type_vr": (ERROR, "a Real variable, not of type Integer"),
    "step_huge": (ERROR, "fmi2DoStep: communicationStepSize = 1e+300 s is longer than this FMU's longest step"),
    "step_negative": (ERROR, "fmi2DoStep: communicationStepSize = -1: a step must be finite and > 0"),
    "step_zero": (ERROR, "fmi2DoStep: communicationStepSize = 0: a step must be finite and > 0"),
    "step_nan": (ERROR, "fmi2DoStep: communicationStepSize = nan: a step must be finite and > 0"),
    "step_infinite": (ERROR, "fmi2DoStep: communicationStepSize = inf: a step must be finite and > 0"),
    "time_nan": (ERROR, "fmi2DoStep: currentCommunicationPoint = nan is not finite"),
    "step_not_from_the_last_end": (ERROR, "fmi2DoStep: currentCommunicationPoint = 5 s, but the instance is at "
                                          "0.10000000000000001 s (a step starts where the last one ended"),
    "step_past_stop_time": (ERROR, "fmi2DoStep: the step [1, 1.5] s ends after stopTime = 1 s"),
    "null_status_value": (ERROR, "fmi2GetRealStatus: value (where to write the status) is NULL"),
    "null_fmu_state": (ERROR, "fmi2GetFMUstate: FMUstate (the fmi2FMUstate* to fill) is NULL"),
    "format_guard": (ERROR, "(instance '%s%n%s%n', state instantiated)"),
}
ACCEPTED_LOCATIONS = ["resource_file_one_slash", "resource_file_three_slashes", "resource_file_localhost",
                      "resource_trailing_slash", "resource_percent_encoded", "resource_plain_path"]
FALLBACK_LOCATIONS = ["resource_null", "resource_empty"]
NO_LOGGER = {"callbacks_null": "fmi2Instantiate: functions (the callbacks) is NULL",
             "logger_null": "fmi2Instantiate: functions->logger is NULL"}
NULL_INSTANCE = ["fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2Terminate"]


@dataclass(frozen=True)
class HostRun:
    """What the hostile host printed for one FMU: each case's results and log lines."""

    results: dict[str, str]
    logs: dict[str, list[tuple[int, str, str]]]
    stderr: str
    fixed: str

    def status(self, case: str) -> str:
        return self.results[case]


@pytest.fixture(scope="session")
def hostile_host(tmp_path_factory) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (cc or gcc) on PATH to build tests/hostile_host.c")
    host = tmp_path_factory.mktemp("hostile") / "hostile_host"
    subprocess.run([compiler, "-O1", "-Wall", "-Werror", "-o", str(host), str(HOST_SOURCE), "-ldl"], check=True)
    return host


def host_arguments(fmu_path: Path, folder: Path) -> tuple[list[str], str]:
    """The hostile host's arguments after the folder, for ``fmu_path`` extracted into ``folder``,
    and the name of the fixed parameter it sets ("" if none)."""
    fmu = unzip(fmu_path, folder)
    variables = read_model_description(str(folder)).modelVariables
    real = next(v for v in variables if v.type == "Real" and v.causality == "output")
    fixed = next((v for v in variables if v.causality == "parameter" and v.variability == "fixed"
                  and v.type in ("Real", "Integer", "Boolean")), None)
    inputs = [v for v in variables if v.type == "Real" and v.causality == "input"]
    tunable = next((v for v in variables if v.type == "Real" and v.variability == "tunable"), None)
    arguments = [fmu.identifier, fmu.guid, str(real.valueReference),
                 str(fixed.valueReference) if fixed else "-", fixed.type[0] if fixed else "-",
                 str(inputs[0].valueReference) if inputs else "-", str(tunable.valueReference) if tunable else "-"]
    return arguments, fixed.name if fixed else ""


def parse_host_output(completed: subprocess.CompletedProcess, fixed: str) -> HostRun:
    """The results and log lines the host printed (it must have ended by itself)."""
    assert completed.returncode == 0, f"the host crashed ({completed.returncode}):\n{completed.stdout[-3000:]}\n" \
                                      f"{completed.stderr[-3000:]}"
    assert completed.stdout.rstrip().endswith("done")
    results, logs = {}, {}
    for line in completed.stdout.splitlines():
        if line.startswith("result "):
            _, case, value = line.split(" ", 2)
            results[case] = value
        elif line.startswith("log "):
            _, case, status, category, message = line.split(" ", 4)
            logs.setdefault(case, []).append((int(status), category, message))
    return HostRun(results, logs, completed.stderr, fixed)


def run_hostile_host(host: Path, fmu_path: Path, folder: Path) -> HostRun:
    arguments, fixed = host_arguments(fmu_path, folder)
    completed = subprocess.run([str(host), str(folder), *arguments], capture_output=True, text=True, timeout=300,
                               env=environment())
    return parse_host_output(completed, fixed)


@pytest.fixture(scope="module")
def runs(hostile_host, built_fmus, tmp_path_factory) -> dict[str, HostRun]:
    """The hostile host run once on each FMU (a few seconds each)."""
    folder = tmp_path_factory.mktemp("hostile-fmus")
    return {name: run_hostile_host(hostile_host, built_fmus[name], folder / name) for name in fmu_names()}


@pytest.mark.parametrize("name", fmu_names())
def test_every_misuse_is_refused_with_one_log_line(runs, name):
    run = runs[name]
    failures = []
    for case, (expected, text) in REFUSED.items():
        lines = run.logs.get(case, [])
        if run.status(case) != str(expected):
            failures.append(f"{case}: returned {run.status(case)}, expected {expected}")
        elif len(lines) != 1 or text not in lines[0][2] or lines[0][:2] != (ERROR, "logStatusError"):
            failures.append(f"{case}: log lines {lines}, expected one error line holding {text!r}")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("name", fmu_names())
def test_every_rfc_8089_resource_location_runs_and_a_missing_one_falls_back_with_a_warning(runs, name):
    run = runs[name]
    for case in ACCEPTED_LOCATIONS + FALLBACK_LOCATIONS:
        assert (run.status(case), run.status(f"{case}_step")) == ("instance", str(OK)), case
    for case in ACCEPTED_LOCATIONS:
        assert case not in run.logs, case
    for case in FALLBACK_LOCATIONS:
        assert run.logs[case] == [(1, "logStatusWarning", "fmi2Instantiate: fmuResourceLocation is NULL or empty: "
                                                          "using the FMU's own resources folder")]


@pytest.mark.parametrize("name", fmu_names())
def test_null_callbacks_and_null_instance_say_so_on_stderr(runs, name):
    run = runs[name]
    for case, text in NO_LOGGER.items():
        assert run.status(case) == "null" and run.stderr.count(text) == 1, case
    for function in NULL_INSTANCE:
        assert run.stderr.count(f"greyfmu: {function}: the instance (fmi2Component) is NULL") == 1, function
    assert [run.status(f"null_instance_{kind}") for kind in ("step", "get", "set", "terminate")] == [str(ERROR)] * 4


@pytest.mark.parametrize("name", fmu_names())
def test_the_error_state_allows_get_and_reset_which_starts_over(runs, name):
    run = runs[name]
    assert [run.status(case) for case in ("error_state_enter", "error_state_get", "error_state_reset",
                                          "error_state_step_after_reset")] == [str(ERROR), str(OK), str(OK), str(OK)]
    assert [line[2].split(":")[0] for line in run.logs["error_state_until_reset"]] == \
        ["fmi2DoStep", "fmi2EnterInitializationMode"]
    assert run.logs["error_state_until_reset"][1][2].endswith("state error)")
    assert run.status("unknown_vr_then_get") == str(OK)  # fmi2Error, not fmi2Fatal: the instance is not lost
    assert run.status("empty_arrays") == str(OK)
    assert run.status("step_to_stop_time") == str(OK)  # a step ending at stopTime up to rounding is fine


@pytest.mark.parametrize("name", fmu_names())
def test_a_fixed_parameter_set_after_initialisation_is_refused_and_unchanged(runs, name):
    run = runs[name]
    if not run.fixed:
        assert run.status("set_fixed_after_init") == "skip"
        return
    assert run.status("set_fixed_after_init") == str(ERROR) and run.status("set_fixed_unchanged") == "1"
    (status, _, message), = run.logs["set_fixed_after_init"]
    assert re.search(rf"vr\[0\] = \d+: {re.escape(run.fixed)} is a fixed parameter: after initialisation only "
                     r"inputs and tunable parameters can be set \(instance 'hostile', state stepComplete\)", message)


@pytest.mark.parametrize("name", fmu_names())
def test_a_tunable_parameter_set_after_initialisation_is_taken(runs, name):
    run = runs[name]
    if run.status("set_tunable_after_init") == "skip":
        return
    assert (run.status("set_tunable_after_init"), run.status("set_tunable_changed")) == (str(OK), "1")
    assert "set_tunable_after_init" not in run.logs


def test_the_tunable_case_runs_somewhere(runs):
    assert [name for name, run in runs.items() if run.status("set_tunable_after_init") != "skip"] == ["SOPDTPredictive"]


@pytest.mark.parametrize("name", fmu_names())
def test_the_slaves_own_messages_reach_the_host_as_data(runs, name):
    """The slave logs '<instance name>: input ... is not a finite number'; the instance is named
    %s%n%s%n, which the host's vsnprintf would have executed as a format."""
    run = runs[name]
    if run.status("format_slave") == "skip":
        return
    assert run.status("format_slave") == str(DISCARD)
    (status, category, message), = run.logs["format_slave"]
    assert status == ERROR and message.startswith("%s%n%s%n: input ") and "is not a finite number" in message


COSIM_LOGGER = '''
import collections, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from cosim.run.instances.fmi2 import _LOG_TARGETS, _callbacks

fmu = sys.argv[1]
md = read_model_description(fmu)
vr = {v.name: v.valueReference for v in md.modelVariables}
name = "%s%n%s%n"
_LOG_TARGETS[name] = messages = collections.deque()
slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier="PID", instanceName=name)
slave.instantiate(callbacks=_callbacks(), loggingOn=True)
slave.setupExperiment(startTime=0.0)
slave.enterInitializationMode()
slave.exitInitializationMode()
slave.setReal([vr["r"]], [float("nan")])
try:
    slave.doStep(0.0, 0.1)
except Exception as error:
    print("status", error.status)
print("messages", list(messages))
'''


def test_cosims_logger_gets_the_slaves_message_as_data(built_fmus, tmp_path):
    """cosim's FMI 2.0 callbacks (fmpy's native logger proxy formats the printf arguments) get
    the slave's message naming the instance %s%n%s%n verbatim; in a fresh process, as a
    message taken for a format would crash it."""
    completed = subprocess.run([sys.executable, "-c", COSIM_LOGGER, str(built_fmus["PID"])], capture_output=True,
                               text=True, timeout=120, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert "status 2" in completed.stdout
    assert "'[Error] logStatusError: %s%n%s%n: input r = nan at t = 0.0 s is not a finite number'" in completed.stdout
