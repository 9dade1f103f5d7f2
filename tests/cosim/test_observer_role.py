"""Recording as one role (issue 29): every sink, the root-output columns and the journal are a
`cosim.record.observers.Observer` fed by one `Recorder`; the derived columns have one formula (the
live run's and a journal's recovery give the same bytes); `cosim.run.simulation.run` returns a
frozen `cosim.run.outcome.RunOutcome`, and a run that fails half way leaves every row up to the
failure in every observer and in the outcome its error carries.  The FMU is a C FMU compiled
here (tests/cfmus.py), whose step returns fmi2Error once it would pass t = 0.5."""
from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cfmus import build_c_fmu, fmi2_description
from cosim.errors import Errc, RunError
from cosim.record.journal import RunJournal, journal_path, recover
from cosim.record.observers import CsvSink, DerivedColumns, MemorySink, Observer, ParquetSink, Recorder, file_sink
from cosim.run.outcome import RunOutcome
from cosim.record.results import read
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from cosim.model.structure import RecordedOutput
from cosim.model.transforms import Affine
from ssdgen import ssd_text, write_system

RAMP_BODY = ("static void start(S *s) {}\n"
             "static void calculate(S *s) { s->r[0] = 2.0 * s->time + 1.0; }\n"
             "static int step(S *s, double t, double h) { return t + h > 0.5 + 1e-9 ? 3 : 0; }\n")


@pytest.fixture(scope="module")
def ramp(tmp_path_factory) -> Path:
    """y = 2 t + 1; fmi2DoStep returns Error for a step ending after t = 0.5."""
    description = fmi2_description("Ramp", [("y", 0, "output", None)], {"y": []},
                                   "{7a3e0000-0000-4000-8000-000000000029}")
    return build_c_fmu(tmp_path_factory.mktemp("ramp"), "Ramp", description, RAMP_BODY)


def _system(tmp_path: Path, ramp: Path, stop: float) -> Path:
    return write_system(tmp_path / "sys", {"Ramp.fmu": ramp},
                        ssd_text("ramp", {"r": ("Ramp.fmu", {"y": "output"})}, [], stop=stop, step=0.1))


def _outputs() -> list[RecordedOutput]:
    """Two root outputs on the recorded columns: 1.8 a.y + 32 (degC -> degF) and 0 time + 2.5."""
    return [RecordedOutput("f", "a", "y", Affine(1.8, 32.0), "degF"), RecordedOutput("held", None, None, Affine(0.0, 2.5), None)]


def _record(recorder: Recorder, values: np.ndarray, rows: int) -> None:
    for k in range(rows):
        values[:] = (np.sin(0.37 * k), np.cos(1.1 * k) * 1e-3)
        recorder.record(k * 0.01)


def test_every_recording_class_is_an_observer(tmp_path):
    derived = DerivedColumns.of([], ["time"])
    for observer in (CsvSink(tmp_path / "r.csv"), ParquetSink(tmp_path / "r.parquet"), MemorySink(),
                     RunJournal(tmp_path / "r.csv", ["time"], derived, {})):
        assert isinstance(observer, Observer), type(observer)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_the_memory_and_file_observers_receive_the_same_rows(tmp_path, suffix):
    """10000 rows (three chunks) through the root-output columns to memory and to a file: the
    same bits in both, the derived columns factor * source + offset."""
    values = np.zeros(2)
    names = ["a.y", "b.u"]
    memory, path = MemorySink(), tmp_path / f"r{suffix}"
    derived = DerivedColumns.of(_outputs(), ["time"] + names)
    recorder = Recorder(["b.u", "a.y"], [values], names, [memory, file_sink(path)], derived=derived)
    _record(recorder, values, 10000)
    recorder.close({"status": "completed"})
    kept, written = memory.array(), read(path)
    assert kept.dtype.names == written.dtype.names == ("time", "a.y", "b.u", "f", "held") and len(kept) == 10000
    assert kept.tobytes() == written.tobytes()
    assert np.array_equal(kept["a.y"], np.cos(1.1 * np.arange(10000)) * 1e-3)  # b.u's source: the permutation
    assert np.array_equal(kept["f"], kept["a.y"] * 1.8 + 32.0) and set(kept["held"]) == {2.5}


def test_a_recovered_journal_is_the_live_result_byte_for_byte(tmp_path):
    """The journal of a run (copied after 5000 rows, as a crash would leave it) recovers to the
    same CSV bytes, root-output columns included, as the run itself writes on closing."""
    values = np.zeros(2)
    names = ["a.y", "b.u"]
    live = tmp_path / "live" / "r.csv"
    derived = DerivedColumns.of(_outputs(), ["time"] + names)
    recorder = Recorder(["a.y", "b.u"], [values], names, [file_sink(live)], derived=derived,
                        journal=RunJournal(live, ["time"] + names, derived, {"scenario": "s"}))
    _record(recorder, values, 5000)
    crashed = tmp_path / "crashed" / "r.csv"
    crashed.parent.mkdir()
    shutil.copy(journal_path(live), journal_path(crashed))
    recorder.close({"status": "completed"})
    assert not journal_path(live).exists()
    assert recover(journal_path(crashed)) == (crashed.resolve(), 5000)
    assert crashed.read_bytes() == live.read_bytes()
    meta = json.loads(crashed.with_suffix(".json").read_text())
    assert (meta["status"], meta["error"], meta["samples"], meta["scenario"]) == ("crashed", "run_process_lost", 5000, "s")


@pytest.mark.parametrize("rows", [5000, 5120, 7])
def test_a_csv_journal_is_one_window_and_recovers_with_the_part_file(tmp_path, rows):
    """Issue 42: beside a CSV the journal is a ring of one window (256 rows here) written over once
    the part file holds its rows, not a copy of every row; the part file and the journal a crash
    leaves (copied after ``rows`` rows: mid-window, at a window's end, before any flush) recover
    to the live result's bytes, and so does a journal left after the result was put in place."""
    from cosim.safeio import partial_path

    values = np.zeros(2)
    names = ["a.y", "b.u"]
    live = tmp_path / "live" / "r.csv"
    derived = DerivedColumns.of(_outputs(), ["time"] + names)
    sink = file_sink(live)
    recorder = Recorder(["a.y", "b.u"], [values], names, [sink], derived=derived, chunk_rows=256,
                        journal=RunJournal(live, ["time"] + names, derived, {"scenario": "s"}, chunk_rows=256,
                                           durable=sink))
    _record(recorder, values, rows)
    assert journal_path(live).stat().st_size < 64 * 1024   # one window of 256 x 6 doubles, and the header
    crashed = tmp_path / "crashed" / "r.csv"
    crashed.parent.mkdir()
    shutil.copy(journal_path(live), journal_path(crashed))
    shutil.copy(partial_path(live), partial_path(crashed))
    recorder.flush()
    late = tmp_path / "late.journal"   # as a process killed after its result was in place would leave it
    shutil.copy(journal_path(live), late)
    recorder.close({"status": "completed"})
    assert recover(journal_path(crashed)) == (crashed.resolve(), rows)
    assert crashed.read_bytes() == live.read_bytes() and len(read(crashed)) == rows
    published = live.read_bytes()
    shutil.copy(late, journal_path(live))
    assert recover(journal_path(live)) == (live.resolve(), rows) and live.read_bytes() == published


def test_a_completed_run_returns_a_frozen_outcome(tmp_path, ramp):
    out = tmp_path / "ok.csv"
    prepared = prepare(_system(tmp_path, ramp, stop=0.5))
    try:
        outcome = run(prepared, output=out)
    finally:
        prepared.close()
    assert isinstance(outcome, RunOutcome)
    assert (outcome.status, outcome.message, outcome.error, outcome.output) == ("completed", "", None, out)
    assert outcome.samples == 6 and outcome.result.tobytes() == read(out).tobytes()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert list(meta) == list(outcome.metadata) and meta["status"] == "completed" and meta["error"] is None
    result, metadata = outcome
    assert result is outcome.result is outcome[0] and metadata is outcome.metadata is outcome[1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        outcome.status = "failed"


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_run_failing_half_way_keeps_its_rows_in_every_observer_and_in_the_outcome(tmp_path, ramp, suffix):
    out = tmp_path / f"failed{suffix}"
    prepared = prepare(_system(tmp_path, ramp, stop=1.0))
    try:
        with pytest.raises(RunError) as caught:
            run(prepared, output=out)
    finally:
        prepared.close()
    outcome = caught.value.run_outcome
    assert isinstance(outcome, RunOutcome) and caught.value.result is outcome.result
    assert (outcome.status, outcome.error, outcome.output) == ("failed", Errc.model_error, out)
    assert "fmi2DoStep returned Error at t = 0.5" in outcome.message and outcome.message == str(caught.value)
    assert list(outcome.result["time"]) == pytest.approx([0.1 * k for k in range(6)])  # every step before t = 0.5
    assert np.array_equal(outcome.result["r.y"], 2.0 * outcome.result["time"] + 1.0)
    assert read(out).tobytes() == outcome.result.tobytes()
    meta = json.loads(out.with_suffix(".json").read_text())
    assert (meta["status"], meta["error"], meta["message"]) == ("failed", "model_error", outcome.message)
    assert outcome.metadata["status"] == "failed" and not journal_path(out).exists()


def test_an_error_extended_after_the_run_is_a_new_error_of_the_same_kind():
    """What `cosim.run.simulation.run` says when the metadata JSON fails after the disk filled up:
    a copy with the text appended (class, code, file and run outcome kept), the original as it was."""
    from cosim.errors import OutOfMemory

    first = OutOfMemory("the process ran out of memory at t = 3; the 30 rows recorded before are kept.",
                        file="r.csv")
    later = first.extended(" The metadata JSON could not be written either (the disk is full)")
    assert type(later) is OutOfMemory and later.code is Errc.out_of_memory and later.file == "r.csv"
    assert str(later) == ("r.csv: the process ran out of memory at t = 3; the 30 rows recorded before are kept."
                          " The metadata JSON could not be written either (the disk is full)")
    assert str(first).endswith("are kept.") and later is not first
