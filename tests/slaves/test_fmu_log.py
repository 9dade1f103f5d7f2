"""The FMU-log bridge (greyfmu/forwarding.py, wrapped around build/advance/retune in fmus/_slave.py).

greyfmu's warnings reach the FMU log of the instance that caused them, for any slave: here a
GainScheduledPID whose slave has no logging code of its own, through a real FMU under fmpy.
"""

import logging
import subprocess
import sys
import threading
import time
import warnings

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from greyfmu.forwarding import forward_from, keep_routing


class Sink:
    """A `greyfmu.forwarding.WarningSink` whose ``call`` is registered as a slave's methods are."""

    def __init__(self) -> None:
        self.got: list[str] = []

    def forward_warning(self, message: str) -> None:
        self.got.append(message)

    def call(self, body) -> None:
        keep_routing()
        body()


forward_from(Sink.call)


def greyfmu_warnings() -> None:
    logging.getLogger("greyfmu.control.gpc").warning("QP %s", "infeasible")
    logging.getLogger("greyfmu.control.gpc").info("not a warning")
    logging.getLogger("elsewhere").warning("not greyfmu's")
    warnings.warn("design outside the advice")


def test_warnings_reach_the_sink_whose_call_raised_them_every_occurrence_whatever_the_host_filters():
    """Records of greyfmu's loggers at WARNING and above and Python warnings, raised in a sink's call,
    reach that sink, every time, not another sink; outside a call the host's filters decide (here
    "error" raises, as without greyfmu)."""
    first, second = Sink(), Sink()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a host's filter in front of the route, which the call puts back
        first.call(greyfmu_warnings)
        second.call(greyfmu_warnings)
        first.call(greyfmu_warnings)
        try:
            warnings.warn("outside")
        except UserWarning as raised:
            assert str(raised) == "outside"
        else:
            raise AssertionError("a warning outside the sinks' calls met the host's 'error' filter and was not raised")
    logging.getLogger("greyfmu.control.gpc").warning("after the calls")
    assert first.got == ["QP infeasible", "design outside the advice"] * 2
    assert second.got == ["QP infeasible", "design outside the advice"]


def test_a_record_outside_any_call_reaches_stderr_as_without_the_handler():
    """greyfmu used as a library, with no logging configured: a warning outside any sink's call still
    reaches Python's last-resort handler (stderr), though greyfmu's logger now has a handler."""
    code = ("import logging; from greyfmu import forwarding; "
            "logging.getLogger('greyfmu.control.gpc').warning('QP %s', 'infeasible')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert done.stderr == "QP infeasible\n"


def test_threads_calling_two_sinks_at_once_each_get_their_own_warnings():
    """Two threads in two sinks' calls at once, taking turns (each lets the other run after each
    warning): each sink gets its own thread's warnings, all of them."""
    sinks, order = [Sink() for _ in range(2)], []
    barrier = threading.Barrier(2)

    def run(index: int) -> None:
        def body() -> None:
            barrier.wait()
            for k in range(300):
                order.append(index)
                warnings.warn(f"sink {index} warning {k}")
                time.sleep(0)  # the other thread may run

        sinks[index].call(body)

    threads = [threading.Thread(target=run, args=(index,)) for index in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    switches = sum(a != b for a, b in zip(order, order[1:]))
    assert switches >= 10, f"the threads took turns {switches} times only"
    for index, sink in enumerate(sinks):
        assert sink.got == [f"sink {index} warning {k}" for k in range(300)]


def test_a_slave_without_logging_code_forwards_its_controllers_warning(built_fmus, tmp_path, capfd):
    """ITAE law (law = 4): a process time constant T = -1 is refused; the PID holds its gains and says so."""
    path = built_fmus["GainScheduledPID"]
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(path, tmp_path),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="gs")
    fmu.instantiate(loggingOn=True)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setInteger([refs["law"]], [4])
        fmu.exitInitializationMode()
        fmu.setReal([refs["r"]], [1.0])
        fmu.doStep(0.0, 1.0)
        gains = fmu.getReal([refs["Kc"], refs["Ti"]])
        capfd.readouterr()
        fmu.setReal([refs["T"]], [-1.0])
        fmu.doStep(1.0, 1.0)
        assert fmu.getReal([refs["Kc"], refs["Ti"]]) == gains
        log = capfd.readouterr().out
        assert "gs: GainScheduledPID: scheduling variable refused" in log and "time constant T must be" in log
        fmu.terminate()
    finally:
        fmu.freeInstance()


def started(path, name: str, folder, integers: dict[str, int] | None = None) -> tuple[FMU2Slave, dict[str, int]]:
    """An instance ``name`` of the FMU at ``path`` under fmpy (logging on), initialised at t = 0 with
    the Integer parameters ``integers``."""
    description = read_model_description(path)
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(path, folder / name),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(loggingOn=True)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    refs = {v.name: v.valueReference for v in description.modelVariables}
    for parameter, value in (integers or {}).items():
        fmu.setInteger([refs[parameter]], [value])
    fmu.exitInitializationMode()
    return fmu, refs


def test_a_warning_raised_in_one_of_two_instances_reaches_its_log_only_every_time(built_fmus, tmp_path, capfd):
    """SOPDTPredictive retuned to T0 = 300 s re-designs with N = [(90 + 3*300)/40] = 24 > 20: greyfmu
    warns (HorizonWarning, a Python warning, in the retune called by fmi2SetReal).  Of two instances
    in one process, the one retuned says it; the other, retuned next, says it too (the same warning
    from the same line: not swallowed as already shown); the first, retuned again, again."""
    path = built_fmus["SOPDTPredictive"]
    first, refs = started(path, "first", tmp_path)
    second, _ = started(path, "second", tmp_path)
    try:
        said, time = [], {"first": 0.0, "second": 0.0}
        for fmu, t0 in ((first, 300.0), (second, 300.0), (first, 320.0)):
            capfd.readouterr()
            fmu.setReal([refs["T0"]], [t0])
            fmu.doStep(time[fmu.instanceName], 40.0)
            time[fmu.instanceName] += 40.0
            said.append([line for line in capfd.readouterr().out.splitlines() if "horizon N" in line])
        message = ("SOPDTPredictive: horizon N = [(tau + 3 T0)/Ts] = {} exceeds the paper's limit of 20 (N in 15..20)")
        assert [len(lines) for lines in said] == [1, 1, 1], said
        assert said[0][0].startswith(f"[WARNING] first: {message.format(24)}")
        assert said[1][0].startswith(f"[WARNING] second: {message.format(24)}")
        assert said[2][0].startswith(f"[WARNING] first: {message.format(26)}")
        assert first.getReal([refs["N"]]) == [26.0] and second.getReal([refs["N"]]) == [24.0]
    finally:
        for fmu in (first, second):
            fmu.terminate()
            fmu.freeInstance()


def test_two_fmus_of_ours_share_one_route_and_each_logs_its_own_law_s_warnings(built_fmus, tmp_path, capfd):
    """A GainScheduledPID whose scheduling variable T = -1 is refused at every sample (a greyfmu
    logging warning in its law) and a SOPDTPredictive whose retune warns (a Python warning), stepped
    in turn in one process, each with its own private copy of greyfmu.forwarding: each warning reaches
    its own instance's log, every time, and ``warnings.filters`` holds one route, at its front, the
    same entry before and after (no copy takes the front from another at each step)."""
    scheduled, scheduled_refs = started(built_fmus["GainScheduledPID"], "gs", tmp_path, {"law": 4})  # ITAE: Kp, T, tau
    sopdt, sopdt_refs = started(built_fmus["SOPDTPredictive"], "sopdt", tmp_path)
    try:
        scheduled.doStep(0.0, 1.0)  # gains to hold from here on
        scheduled.setReal([scheduled_refs["T"]], [-1.0])
        head = warnings.filters[0]
        said = []
        for k in range(3):
            capfd.readouterr()
            scheduled.doStep(1.0 + k, 1.0)
            sopdt.setReal([sopdt_refs["T0"]], [300.0 + 10 * k])
            sopdt.doStep(k * 40.0, 40.0)
            said.append(capfd.readouterr().out.splitlines())
        for lines in said:
            assert sum(line.startswith("[WARNING] gs: GainScheduledPID: scheduling variable refused") for line in lines) \
                == 10, lines  # Ts = 0.1 s: ten samples a step, each refused
            assert sum(line.startswith("[WARNING] sopdt: SOPDTPredictive: horizon N") for line in lines) == 1, lines
            assert not any("gs:" in line and "horizon" in line or "sopdt:" in line and "scheduling" in line
                           for line in lines)
        routes = [entry for entry in warnings.filters if getattr(entry[1], "greyfmu_route", None) == 1]
        assert routes == [head] and warnings.filters[0] is head
    finally:
        for fmu in (scheduled, sopdt):
            fmu.terminate()
            fmu.freeInstance()
