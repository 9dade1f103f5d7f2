"""``--isolate`` (issue 17): each component in a process of its own (`cosim.run.instances.isolated`).

A crashing FMU (abort, segfault, _exit: tests/fmus/Faulty.py) is that component's failure,
named with its FMU file, the FMI call, the signal or exit status and t, the rows up to the
fault kept and the JSON written by the master itself (status "crashed"); a hung call ends
after ``--call-timeout`` (status "timeout"); the components' processes are reaped and leave
no folder behind; results equal the in-process run sample by sample (our pythonfmu FMUs in
pid_fopdt, C FMUs of FMI 2.0 and 3.0 with every exchange type, String connections).
"""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from cosim.errors import ComponentLost
from cosim.record.results import read
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus
from typefmus import BYTES3, BYTES3_BODY, MODES2, MODES2_BODY, OUTPUTS3, TYPES3, TYPES3_BODY



def _sibling(path: str):
    """A test module of another folder (its FMU sources), loaded under its own name."""
    spec = importlib.util.spec_from_file_location(f"isolate_{Path(path).stem}", Path(__file__).parent / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


CRASHES = [(1, "crashed with SIGABRT"), (2, "crashed with SIGSEGV"), (3, "exited with status 3")]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    return build_test_fmus(tmp_path_factory.mktemp("isolate"))


def _faulty(tmp_path: Path, fmus, fault: int, fault_time: float, stop: float = 20.0, step: float = 0.5,
            **extra) -> Path:
    comps = {"f": ("Faulty.fmu", {"y": "output"}), "g": ("Faulty.fmu", {"y": "output"})}
    params = {"f": {"fault": fault, "fault_time": fault_time, **extra}}
    return write_system(tmp_path / "sys", {"Faulty.fmu": fmus["Faulty"]},
                        ssd_text("faulty", comps, [], stop=stop, step=step, parameters=params))


def _children() -> set[int]:
    """The live child processes of this process."""
    found = set()
    for task in Path("/proc/self/task").iterdir():
        found.update(int(p) for p in (task / "children").read_text().split())
    return found


def _processes_naming(text: str) -> list[int]:
    """Processes whose command line contains ``text`` (a scenario's folder)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and text in (proc / "cmdline").read_bytes().decode(errors="replace"):
                found.append(int(proc.name))
        except OSError:
            pass
    return found


@pytest.mark.parametrize("fault, how", CRASHES)
def test_a_crashing_component_is_named_its_rows_kept_and_its_process_reaped(tmp_path, fmus, fault, how):
    folder = _faulty(tmp_path, fmus, fault, fault_time=5.0)
    before = _children()
    out = tmp_path / "out.csv"
    with pytest.raises(ComponentLost) as caught:
        cosim.simulate(folder, output=out, isolate=True)
    e = caught.value
    assert str(e) == f"component 'f' (Faulty.fmu): {how} during fmi2DoStep at t = 5."
    assert e.component == "f" and e.outcome == "crashed" and e.time == 5.0
    assert list(e.result["time"]) == pytest.approx([0.5 * k for k in range(11)])  # every step before t = 5
    assert list(read(out)["f.y"]) == pytest.approx([0.5 * k for k in range(11)])
    assert list(read(out)["g.y"]) == pytest.approx([0.5 * k for k in range(11)])  # the other one too
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["status"] == "crashed" and meta["message"] == str(e) and meta["last_time"] == 5.0
    assert e.code.value == meta["error"] == "component_crashed"
    assert meta["isolation"] == {"call_timeout": None}
    assert meta["kernel"] == "python" and "component 'f' runs in a process of its own (--isolate)" in meta["kernel_reason"]
    assert not out.with_name("out.csv.journal").exists()
    assert _children() <= before  # f's process reaped after its crash, g's after being freed


def test_a_hung_call_ends_after_the_call_timeout(tmp_path, fmus):
    folder = _faulty(tmp_path, fmus, 4, fault_time=3.0)
    before = _children()
    started = time.monotonic()
    with pytest.raises(ComponentLost) as caught:
        cosim.simulate(folder, output=tmp_path / "out.csv", isolate=True, call_timeout=0.5)
    elapsed = time.monotonic() - started
    assert str(caught.value) == ("component 'f' (Faulty.fmu): fmi2DoStep did not return within 0.5 s at t = 3; "
                                 "the component's process was killed.")
    assert 0.5 <= elapsed < 5  # the hang is an hour
    meta = json.loads((tmp_path / "out.json").read_text())
    assert meta["status"] == "timeout" and meta["last_time"] == 3.0 and meta["isolation"]["call_timeout"] == 0.5
    assert meta["error"] == "component_timeout"
    assert list(read(tmp_path / "out.csv")["time"]) == pytest.approx([0, 0.5, 1, 1.5, 2, 2.5, 3])
    assert _children() <= before


def test_call_timeout_needs_isolate_and_a_positive_number(tmp_path, fmus):
    folder = _faulty(tmp_path, fmus, 0, fault_time=0.0, stop=1.0)
    with pytest.raises(cosim.SetupError, match="--call-timeout: it needs --isolate"):
        cosim.simulate(folder, call_timeout=1.0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(cosim.SetupError, match="--call-timeout.*positive number of seconds"):
            cosim.simulate(folder, isolate=True, call_timeout=bad)


def test_fmu_log_messages_reach_the_error(tmp_path, fmus):
    """Failing.fmu logs why it refuses the step, then raises (fmi2Fatal): the message is the
    in-process one, the FMU's log included."""
    comps = {"f": ("Failing.fmu", {"u": "input", "y": "output"})}
    folder = write_system(tmp_path / "s", {"Failing.fmu": fmus["Failing"]},
                          ssd_text("failing", comps, [], stop=1.0, step=0.1, parameters={"f": {"fail_time": 0.45}}))
    messages = []
    for isolate in (False, True):
        with pytest.raises(cosim.RunError) as caught:
            cosim.simulate(folder, isolate=isolate)
        messages.append(str(caught.value))
    assert "refusing the step from t = 0.4" in messages[1] and "fmi2DoStep returned Fatal at t = 0.4" in messages[1]
    assert messages[0] == messages[1]


def _cosim(tmp_path: Path, *argv: str, **popen) -> subprocess.Popen:
    env = dict(os.environ, TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return subprocess.Popen([sys.executable, "-m", "cosim.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, **popen)


def test_cli_a_segfault_under_isolate_is_the_components_failure(tmp_path, fmus):
    folder = _faulty(tmp_path, fmus, 2, fault_time=5.0)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "--isolate", "-o", str(csv))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1 and "Traceback" not in err
    assert "component 'f' (Faulty.fmu): crashed with SIGSEGV during fmi2DoStep at t = 5." in err
    assert "recovered from the journal" not in err  # the master wrote the results itself
    assert json.loads(csv.with_suffix(".json").read_text())["status"] == "crashed" and len(read(csv)) == 11
    assert sorted(os.listdir(tmp_path / "tmp")) == [] and _processes_naming(str(folder)) == []


def test_cli_whole_run_timeout_with_isolate_ends_a_hung_component(tmp_path, fmus):
    folder = _faulty(tmp_path, fmus, 4, fault_time=3.0)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "--isolate", "-o", str(csv), "--timeout", "1")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "Traceback" not in err and "did not stop within 2 s" in err
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "timeout" and meta["last_time"] == 3.0
    assert sorted(os.listdir(tmp_path / "tmp")) == []
    deadline = time.monotonic() + 5  # the components' processes die with the master (PR_SET_PDEATHSIG)
    while _processes_naming(str(folder)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _processes_naming(str(folder)) == []


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_cli_ctrl_c_to_the_process_group_stops_at_a_communication_point(tmp_path, fmus, signum, code):
    """A terminal's Ctrl-C (or a SIGTERM to the group) reaches every process of the group: the
    components' processes ignore it and the master stops the run at its next communication
    point, as without --isolate."""
    folder = _faulty(tmp_path, fmus, 5, fault_time=0.0, stop=1000.0, step=0.1, delay=0.01)
    csv = tmp_path / "out.csv"
    proc = _cosim(tmp_path, "run", str(folder), "-q", "--isolate", "-o", str(csv), start_new_session=True)
    deadline = time.monotonic() + 60
    part = csv.with_name(csv.name + ".part")  # written there until the run ends (cosim.safeio.atomic_path)
    while not (part.exists() and part.stat().st_size > 200):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    os.killpg(proc.pid, signum)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code and "Traceback" not in err and f"stopped by {signum.name}" in err, err
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "interrupted" and len(read(csv)) == round(meta["last_time"] / 0.1) + 1


def test_cli_call_timeout_without_isolate_is_refused(tmp_path, fmus):
    folder = _faulty(tmp_path, fmus, 0, fault_time=0.0, stop=1.0)
    proc = _cosim(tmp_path, "run", str(folder), "-q", "--call-timeout", "1", "-o", str(tmp_path / "o.csv"))
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "--call-timeout: it needs --isolate" in err and "Traceback" not in err
    assert not (tmp_path / "o.csv").exists()


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype.names == b.dtype.names
    for name in a.dtype.names:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_pid_fopdt_isolated_equals_in_process(built_fmus):
    ours = cosim.simulate("ssp/pid_fopdt", stop_time=20.0)
    _same(cosim.simulate("ssp/pid_fopdt", stop_time=20.0, isolate=True), ours)
    assert len(ours) == 201


def test_c_fmus_of_fmi2_and_fmi3_isolated_equal_in_process(tmp_path, fmus):
    """Every exchange path through the channel: Real, Integer (FMI 3.0 Int8/Int64/Enumeration
    gathered through scratch buffers), Boolean, Float32, Binary (pointers), FMI 2.0 Enumeration,
    String (pythonfmu Labels), with feedthrough settling; and an FMI 3.0 Model Exchange ball
    integrated in its process."""
    ball = _sibling("../cosim/instances/test_model_exchange_fmi3.py")
    c = tmp_path / "c"
    files = {"Types3.fmu": build_c_fmu(c, "Types3", TYPES3, TYPES3_BODY, "3.0"),
             "Modes2.fmu": build_c_fmu(c, "Modes2", MODES2, MODES2_BODY, "2.0"),
             "Bytes3.fmu": build_c_fmu(c, "Bytes3", BYTES3, BYTES3_BODY, "3.0"),
             "Labels.fmu": fmus["Labels"],
             "Ball3.fmu": build_c_fmu(c, "Ball3", ball.BALL3, ball.BALL3_BODY, "3.0", model_exchange=True)}
    comps = {"a": ("Types3.fmu", {o: "output" for o in OUTPUTS3}),
             "b": ("Types3.fmu", {"fin": "input", "i8in": "input", "i64in": "input", "ein": "input",
                                  "fecho": "output", "sum": "output"}),
             "m": ("Modes2.fmu", {"mode": "output"}), "n": ("Modes2.fmu", {"set": "input", "echo": "output"}),
             "x": ("Bytes3.fmu", {"blob": "output"}),
             "y": ("Bytes3.fmu", {"bin": "input", "length": "output", "checksum": "output"}),
             "p": ("Labels.fmu", {"label": "output"}), "q": ("Labels.fmu", {"text": "input", "length": "output"}),
             "ball": ("Ball3.fmu", {"h": "output", "v": "output"})}
    wires = [("a", "f", "b", "fin"), ("a", "i8", "b", "i8in"), ("a", "i64", "b", "i64in"), ("a", "e", "b", "ein"),
             ("m", "mode", "n", "set"), ("x", "blob", "y", "bin"), ("p", "label", "q", "text")]
    folder = write_system(tmp_path / "all", files, ssd_text("all", comps, wires, stop=1.0, step=0.1))
    ours = cosim.simulate(folder)
    _same(cosim.simulate(folder, isolate=True), ours)
    assert list(ours["q.length"][:2]) == [3, 3] and ours["q.length"][-1] == 4   # 'low', then 'high'
    np.testing.assert_array_equal(ours["y.checksum"], np.arange(11) * (np.arange(11) + 1))
    assert ours["ball.v"][0] == 0 and ours["ball.v"].max() > 0  # it fell and bounced (a state event)


def test_an_fmu_refusing_initialisation_fails_as_it_does_in_process(tmp_path, built_fmus):
    """FOPDT refuses T = 0 when it enters initialisation (fmpy raises in the component's
    process): the exception crosses the wire with its text and FMI status, the message is the
    in-process one, the FMU's log included, and the process is reaped."""
    comps = {"plant": ("FOPDT.fmu", {"y": "output"})}
    folder = write_system(tmp_path / "s", {"FOPDT.fmu": built_fmus["FOPDT"]},
                          ssd_text("refused", comps, [], stop=1.0, step=0.1, parameters={"plant": {"T": 0.0}}))
    before = _children()
    messages = []
    for isolate in (False, True):
        with pytest.raises(cosim.RunError) as caught:
            cosim.simulate(folder, isolate=isolate)
        messages.append(str(caught.value))
    assert "time constant T must be a finite number > 0" in messages[1] and messages[0] == messages[1]
    assert _children() <= before
