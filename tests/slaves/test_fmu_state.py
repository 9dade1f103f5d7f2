"""FMU state of every greyfmu FMU through fmpy: save -> step -> restore -> replay, bit for bit.

FMI 2.0 §2.1.8: after fmi2SetFMUstate the FMU is in the state fmi2GetFMUstate saved, so the
same inputs give the same outputs; a serialised state (fmi2SerializeFMUstate) restored with
fmi2DeSerializeFMUstate, in the same instance or another instance of the FMU, is that state too.
Each FMU declares canGetAndSetFMUstate and canSerializeFMUstate "true" only because this holds.
"""
from __future__ import annotations

import json
import math
import os
import pickle
import shutil
import subprocess
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.model_description import ModelDescription

from greyfmu.build import FMU_SOURCES

NAMES = sorted(path.stem for path in FMU_SOURCES.glob("*.py") if not path.stem.startswith("_"))
BEFORE = 12
"""Steps run before the state is saved."""
AFTER = 16
"""Steps replayed from the saved state."""
MAX_STEPS = 30
"""At most this many default steps per step of the test."""


class Run:
    """One initialised instance of an FMU with its inputs driven by the step index."""

    def __init__(self, description: ModelDescription, folder: str, name: str) -> None:
        self.description = description
        self.slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                               modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
        variables = description.modelVariables
        self.inputs = [(v.valueReference, float(v.start or 0.0)) for v in variables if v.causality == "input"]
        self.outputs = [v.valueReference for v in variables if v.causality == "output" and v.type == "Real"]
        experiment = description.defaultExperiment
        span = min(float(experiment.stopTime), MAX_STEPS * (BEFORE + AFTER) * float(experiment.stepSize))
        self.h = span / (BEFORE + AFTER)  # the default experiment's span (dead times elapse), bounded in cost
        self.t = 0.0
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def step(self, k: int) -> list[float]:
        """Set the inputs of step k (start + a wave, so the state's history matters), step, read every output."""
        if self.inputs:
            self.slave.setReal([vr for vr, _ in self.inputs],
                               [start + 0.05 * (1 + abs(start)) * math.sin(0.7 * k + i) for i, (_, start) in enumerate(self.inputs)])
        self.slave.doStep(self.t, self.h)
        self.t += self.h
        return self.slave.getReal(self.outputs)

    def steps(self, first: int, count: int) -> list[list[float]]:
        return [self.step(k) for k in range(first, first + count)]

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


@pytest.fixture(scope="module")
def unzipped(built_fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory):
    folders: dict[str, tuple[ModelDescription, str]] = {}

    def unzip(name: str) -> tuple[ModelDescription, str]:
        if name not in folders:
            fmu = built_fmus[name]
            folders[name] = read_model_description(fmu), extract(fmu, str(tmp_path_factory.mktemp(name)))
        return folders[name]

    yield unzip
    for _, folder in folders.values():
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("name", NAMES)
def test_declared(unzipped, name: str) -> None:
    description, _ = unzipped(name)
    assert description.coSimulation.canGetAndSetFMUstate
    assert description.coSimulation.canSerializeFMUstate


@pytest.mark.parametrize("name", NAMES)
def test_restored_state_replays_bit_for_bit(unzipped, name: str) -> None:
    description, folder = unzipped(name)
    run = Run(description, folder, "replayed")
    try:
        run.steps(0, BEFORE)
        saved, t = run.slave.getFMUstate(), run.t
        first = run.steps(BEFORE, AFTER)
        run.slave.setFMUstate(saved)
        run.t = t
        assert run.steps(BEFORE, AFTER) == first
        run.slave.setFMUstate(saved)  # a state can be restored again
        run.t = t
        assert run.steps(BEFORE, AFTER) == first
        run.slave.freeFMUstate(saved)
    finally:
        run.close()
    assert any(a != b for a, b in zip(first, first[1:])) or name in CONSTANT_OUTPUTS, \
        f"{name}: the outputs do not change over the replayed steps, so the replay shows nothing"


CONSTANT_OUTPUTS = {"Gain", "Sum", "Step", "LookupTable", "Ramp", "GM3t1Identifier"}
"""FMUs whose outputs may stay constant over the replayed steps with the test's inputs (still checked equal)."""


@pytest.mark.parametrize("name", NAMES)
def test_serialised_state_replays_in_this_and_a_fresh_instance(unzipped, name: str) -> None:
    description, folder = unzipped(name)
    run = Run(description, folder, "serialised")
    fresh = Run(description, folder, "fresh")
    try:
        run.steps(0, BEFORE)
        state = run.slave.getFMUstate()
        data = run.slave.serializeFMUstate(state)
        run.slave.freeFMUstate(state)
        t = run.t
        first = run.steps(BEFORE, AFTER)
        restored = run.slave.deSerializeFMUstate(data)
        run.slave.setFMUstate(restored)
        run.t = t
        assert run.steps(BEFORE, AFTER) == first
        run.slave.freeFMUstate(restored)
        into_fresh = fresh.slave.deSerializeFMUstate(data)
        fresh.slave.setFMUstate(into_fresh)
        fresh.t = t
        assert fresh.steps(BEFORE, AFTER) == first
        fresh.slave.freeFMUstate(into_fresh)
    finally:
        run.close()
        fresh.close()


class _Creates:
    """Pickles as a call of os.mkdir(path): what a hostile serialised state could make pickle.loads do."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self):
        return os.mkdir, (str(self.path),)


@pytest.mark.parametrize("payload", ["hostile", "foreign"])
def test_deserialising_refuses_bytes_that_are_not_our_state(unzipped, tmp_path: Path, payload: str) -> None:
    """A pickle naming os.mkdir is refused without being called; bytes without our header are refused."""
    description, folder = unzipped("PID")
    run = Run(description, folder, "refusing")
    made = tmp_path / "made-by-the-state"
    header = b"greyfmu-fmu-state-2\n" if payload == "hostile" else b"not a state"
    try:
        with pytest.raises(FMICallException, match="fmi2DeSerializeFMUstate"):
            run.slave.deSerializeFMUstate(header + pickle.dumps({"model": "PID", "attributes": _Creates(made)}))
    finally:
        run.slave.freeInstance()
    assert not made.exists()


STATE_BYTES = Path(__file__).resolve().parents[1] / "state_bytes.py"
ACROSS_PYTHONS = ["PID", "GainScheduledPID", "OSMMGPC"]
"""FMUs whose state holds enum members (their mode parameters and controllers' modes)."""


def _state_runs(python: Path, *arguments: str) -> list[dict]:
    from dropinhost import environment

    done = subprocess.run([str(python), str(STATE_BYTES), *arguments], capture_output=True, text=True, timeout=600,
                          env=environment())
    assert done.returncode == 0, f"{python}: exit {done.returncode}\n{done.stderr[-3000:]}"
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def test_a_state_is_the_same_bytes_on_every_python_and_restores_under_another(built_fmus, debian_python, tmp_path):
    """Debian's own python3 (3.11.2, which pickles an enum member as getattr(class, name)) and a
    Python of another build (3.11.7 here, class(value)): the same FMU run the same way serialises
    the same bytes under both, and each one's bytes restore under the other with the outputs the
    saving process went on to compute.  At 96f2739 Debian's bytes differed and no Python could
    restore them ("may not refer to builtins.getattr": 9 FMUs, README command 2 red there)."""
    from pythons import Unavailable, another_python, bare_venv

    try:
        other = bare_venv(another_python())
    except Unavailable as why:
        pytest.skip(str(why))
    fmus = [str(built_fmus[name]) for name in ACROSS_PYTHONS]
    saved = {"debian": _state_runs(debian_python, "save", *fmus), "other": _state_runs(other, "save", *fmus)}
    for debian, theirs in zip(saved["debian"], saved["other"]):
        assert debian["state"] == theirs["state"], f"{debian['fmu']}: the state's bytes depend on the Python"
        assert debian["outputs"] == theirs["outputs"]
    for writer, reader in (("debian", other), ("other", debian_python)):
        states = tmp_path / f"{writer}.json"
        states.write_text(json.dumps({run["fmu"]: run["state"] for run in saved[writer]}))
        restored = _state_runs(reader, "restore", str(states))
        assert [run["outputs"] for run in restored] == [run["outputs"] for run in saved[writer]], writer


def test_the_state_pickle_names_enum_members_by_value_and_classes_by_their_source_name():
    """fmus/_state.py on the Python running the tests: an IntEnum member is its class called with
    its value (no getattr, whatever the Python), a class of the FMU's code is a persistent id with
    the name it has in the sources, and the unpickler refuses a class another module defines even
    when a module of ours imports it (a subprocess.Popen imported by one would run a command)."""
    import io
    import pickletools
    import sys

    sys.path.insert(0, str(FMU_SOURCES))
    try:
        import _state
        from _slave import AntiWindup
    finally:
        sys.path.remove(str(FMU_SOURCES))
    data = _state.state_bytes({"model": "PID", "attributes": {"mode": AntiWindup.NONE}}, "PID")
    listing = io.StringIO()
    pickletools.dis(data[len(_state.STATE_FORMAT):], out=listing)
    text = listing.getvalue()
    assert "getattr" not in text and "GLOBAL" not in text and "BINPERSID" in text
    assert all(f"'{part}'" in text for part in ("class", "_slave", "AntiWindup"))
    assert _state.state_from_bytes(data, "PID", "PID")["attributes"]["mode"] is AntiWindup.NONE

    class Forger(pickle.Pickler):
        def persistent_id(self, obj):  # IntEnum, which greyfmu.control.pid imports from enum
            return ("class", "greyfmu.control.pid", "IntEnum") if obj is Forger else None

    forged = io.BytesIO(_state.STATE_FORMAT)
    forged.seek(0, 2)
    Forger(forged, protocol=5).dump({"model": "PID", "attributes": {"kind": Forger}})
    with pytest.raises(ValueError, match="greyfmu.control.pid.IntEnum, which is not a class of this FMU's code"):
        _state.state_from_bytes(forged.getvalue(), "PID", "PID")
