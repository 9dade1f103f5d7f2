"""Result sinks and the recorder: CSV and Parquet round-trip bit for bit with names and
metadata, a failed run leaves its flushed rows readable in both formats, and the recorder's
memory does not grow with the number of steps."""
from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import cosim
from cfmus import build_c_fmu, fmi2_description
from cosim.cli import main
from cosim.record.observers import CsvSink, MemorySink, ParquetSink, Recorder, file_sink
from cosim.record.results import read
from ssdgen import ssd_text, write_system
from pythonfmu.builder import FmuBuilder
from testfmus import HERE as TEST_FMU_SOURCES

NAMES = ["time", "a.y", "b.u", "b.y"]
METADATA = {"algorithm": "jacobi", "status": "completed", "steps": 7, "nested": {"x": [1, 2]}}


def awkward_rows(n: int, seed: int = 3) -> np.ndarray:
    """Values that stress a text format: 17 significant digits, huge, tiny, subnormal, -0.0, inf, NaN."""
    rows = np.random.default_rng(seed).standard_normal((n, len(NAMES))) * 10.0 ** np.arange(-4, 4 * len(NAMES) - 4, 4)
    rows[0, 1:] = [-0.0, 5e-324, 1.7976931348623157e308]
    rows[1, 1:] = [np.inf, -np.inf, np.nan]
    rows[:, 0] = np.arange(n) * 0.1
    return rows


def write_chunks(sink, chunks: list[np.ndarray]) -> None:
    sink.open(NAMES)
    for chunk in chunks:
        sink.write(chunk)
    sink.close(METADATA)


def assert_bitwise_equal(got: np.ndarray, expected: np.ndarray) -> None:
    assert got.dtype == expected.dtype and got.shape == expected.shape
    assert got.tobytes() == expected.tobytes()


def test_csv_round_trips_bit_for_bit(tmp_path):
    rows = awkward_rows(300)
    path = tmp_path / "r.csv"
    write_chunks(CsvSink(path), [rows[:128], rows[128:]])
    lines = path.read_text().splitlines()
    assert lines[0] == '"time","a.y","b.u","b.y"' and len(lines) == 301
    assert lines[1].split(",")[1:] == ["-0", "5e-324", "1.7976931348623157e+308"]
    assert lines[2].split(",")[1:] == ["inf", "-inf", "nan"]
    result = read(path)  # fmpy.util.read_csv
    assert list(result.dtype.names) == NAMES
    # NaN payloads aside, every float64 comes back with the same bits
    back = np.column_stack([result[n] for n in NAMES])
    assert np.array_equal(back, rows, equal_nan=True) and np.signbit(back[0, 1])
    assert json.loads(path.with_suffix(".json").read_text()) == METADATA


def test_parquet_round_trips_bit_for_bit_one_row_group_per_chunk(tmp_path):
    rows = awkward_rows(300)
    path = tmp_path / "r.parquet"
    write_chunks(file_sink(path), [rows[:128], rows[128:256], rows[256:]])
    parquet = pq.ParquetFile(path)
    assert parquet.metadata.num_row_groups == 3
    table = parquet.read()
    assert table.column_names == NAMES
    assert all(str(field.type) == "double" for field in table.schema)
    back = np.column_stack([table.column(n).to_numpy() for n in NAMES])
    assert_bitwise_equal(back, rows)
    assert json.loads(pq.read_metadata(path).metadata[b"cosim"]) == METADATA
    assert json.loads(path.with_suffix(".json").read_text()) == METADATA


def test_memory_sink_keeps_only_the_columns_asked_for():
    rows = awkward_rows(10)
    sink = MemorySink(keep=["b.y"])
    write_chunks(sink, [rows[:4], rows[4:]])
    result = sink.array()
    assert result.dtype.names == ("time", "b.y")
    assert_bitwise_equal(result["b.y"], rows[:, 3])
    with pytest.raises(ValueError, match="no column named b.z"):
        MemorySink(keep=["b.z"]).open(NAMES)


def test_run_output_and_api_results_agree_in_both_formats(tmp_path, twin_fmus):
    components = {"src": ("Step.fmu", {"y": "output"}),
                  "lag": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("lag", components, [("src", "y", "lag", "u")], stop=2.0, step=0.01,
                    parameters={"src": {"t_step": 0.5}})
    folder = write_system(tmp_path / "sys", {"Step.fmu": twin_fmus["Step"],
                                             "FirstOrderFilter.fmu": twin_fmus["FirstOrderFilter"]}, text)
    result = cosim.simulate(folder, output=tmp_path / "r.parquet")
    cosim.simulate(folder, output=tmp_path / "r.csv")
    table = pq.read_table(tmp_path / "r.parquet")
    csv = read(tmp_path / "r.csv")
    assert table.column_names == list(result.dtype.names) == list(csv.dtype.names)
    for name in result.dtype.names:
        assert_bitwise_equal(table.column(name).to_numpy(), result[name])
        assert_bitwise_equal(csv[name], result[name])
        assert_bitwise_equal(read(tmp_path / "r.parquet")[name], result[name])


def test_metrics_and_compare_read_parquet_as_csv(tmp_path, twin_fmus, capsys):
    """`cosim metrics` gives the same numbers on the Parquet and the CSV of one run, `cosim
    compare` finds them equal, and `results.write` round-trips both formats bit for bit."""
    components = {"src": ("Step.fmu", {"y": "output"}),
                  "lag": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("lag", components, [("src", "y", "lag", "u")], stop=20.0, step=0.01,
                    parameters={"src": {"t_step": 1.0}, "lag": {"T": 2.0}})
    folder = write_system(tmp_path / "sys", {"Step.fmu": twin_fmus["Step"],
                                             "FirstOrderFilter.fmu": twin_fmus["FirstOrderFilter"]}, text)
    result = cosim.simulate(folder, output=tmp_path / "r.parquet")
    cosim.simulate(folder, output=tmp_path / "r.csv")
    capsys.readouterr()
    metrics = []
    for name in ("r.parquet", "r.csv"):
        assert main(["metrics", str(tmp_path / name), "--signal", "lag.y", "--setpoint", "src.y", "--json"]) == 0
        metrics.append(json.loads(capsys.readouterr().out)[0])   # the first (only) event's row
    assert metrics[0] == metrics[1] and metrics[0]["IAE"] == pytest.approx(2.0, rel=1e-2)
    assert main(["compare", str(tmp_path / "r.csv"), str(tmp_path / "r.parquet"), "--rtol", "0", "--atol", "0"]) == 0
    for suffix in (".csv", ".parquet"):
        again = read(cosim.record.results.write(result, tmp_path / f"w{suffix}"))
        for name in result.dtype.names:
            assert_bitwise_equal(again[name], result[name])
    assert not (tmp_path / "w.json").exists()
    (tmp_path / "bad.parquet").write_bytes(b"PAR1 not really")
    assert main(["metrics", str(tmp_path / "bad.parquet"), "--signal", "lag.y", "--setpoint", "src.y"]) == 2
    assert "not a result file" in capsys.readouterr().err


@pytest.mark.parametrize("make_sink", [CsvSink, ParquetSink], ids=["csv", "parquet"])
def test_recorder_memory_does_not_grow_with_the_number_of_steps(tmp_path, make_sink):
    """50 signals recorded for 2 and for 8 chunks of 4096 steps: the peak of the Python
    allocations (one chunk formatted or converted by the sink) is the same."""
    outputs, inputs = np.zeros(25), np.zeros(25)
    names = [f"c{i}.y" for i in range(25)] + [f"c{i}.u" for i in range(25)]

    def peak(chunks: int) -> int:
        tracemalloc.start()
        recorder = Recorder(names, [outputs, inputs], names, [make_sink(tmp_path / f"r{chunks}.out")])
        for k in range(1, chunks * 4096 + 1):
            outputs[:] = k
            inputs[:] = -k
            recorder.record(k * 0.01)
        recorder.close({"steps": chunks * 4096})
        _, high = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        return high

    short, long = peak(2), peak(8)
    assert long < 1.1 * short + 256 * 1024, (short, long)


def test_recorder_reads_the_clock_at_every_row():
    """A slow run is flushed every flush_seconds, not only every 256 rows (issue 17)."""
    import time as _t

    from cosim.record.observers import MemorySink, Recorder

    values = np.zeros(1)
    sink = MemorySink()
    recorder = Recorder(["a.y"], [values], ["a.y"], [sink], chunk_rows=4096, flush_seconds=0.05)
    recorder.record(0.0)
    _t.sleep(0.06)
    recorder.record(1.0)
    assert sink.rows == 2  # flushed after the second row, not the 256th


WIDE_BODY = ("static void start(S *s) {}\n"
             "static void calculate(S *s) { for (int k = 0; k < 32; k++) s->r[k] = (k + 1) * s->time; }\n"
             "static int step(S *s, double t, double h) { s->time = t + h; return 0; }\n")


@pytest.fixture(scope="module")
def wide_system(tmp_path_factory) -> Path:
    """Two C FMUs of 32 outputs each (y_k = (k + 1) t), 8000 steps: 65 columns of 8001 rows."""
    folder = tmp_path_factory.mktemp("wide")
    outputs = [(f"y{k}", k, "output", None) for k in range(32)]
    fmu = build_c_fmu(folder, "Wide", fmi2_description("Wide", outputs, {}, "{7a3e0000-0000-4000-8000-000000000042}"),
                      WIDE_BODY)
    connectors = {name: "output" for name, *_ in outputs}
    return write_system(folder / "sys", {"Wide.fmu": fmu},
                        ssd_text("wide", {"a": ("Wide.fmu", connectors), "b": ("Wide.fmu", connectors)}, [],
                                 stop=0.8, step=1e-4))


def _python_peak(folder: Path, **kw) -> tuple[int, int]:
    """The peak of the Python (and NumPy) allocations of one compiled-loop run of ``folder``, and
    the bytes of its samples (rows x columns x 8)."""
    from cosim.run.simulation import run

    with cosim.prepare(folder, use_providers=False) as prepared:
        tracemalloc.start()
        try:
            outcome = run(prepared, kernel="native", **kw)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert outcome.status == "completed" and outcome.samples == 8001
    return peak, outcome.samples * (1 + len(prepared.plan.columns)) * 8


def test_a_run_holds_its_samples_once_and_a_csv_run_holds_less(tmp_path, wide_system):
    """Issue 42: a run recording in memory holds its samples once (one preallocated array the rows
    are written into, returned as a view: at most 1.5x their bytes at the peak, not a chunk list,
    its concatenation and a structured copy, 3x), writing them to a CSV (only time kept, as
    ``cosim run -o``) holds less than that (a chunk, then one text buffer), and a run that keeps
    only the time and writes no file records only the time (not every column into a chunk)."""
    memory, samples = _python_peak(wide_system)
    assert memory <= 1.5 * samples, (memory, samples)
    written, _ = _python_peak(wide_system, output=tmp_path / "r.csv", keep=[])
    assert written <= memory, (written, memory)
    assert read(tmp_path / "r.csv")["b.y31"][-1] == 32 * 0.8
    only_time, _ = _python_peak(wide_system, keep=[])
    assert only_time <= 0.1 * samples, (only_time, samples)


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


@pytest.fixture(scope="module")
def failing_fmu(tmp_path_factory):
    return FmuBuilder.build_FMU(TEST_FMU_SOURCES / "Failing.py", dest=tmp_path_factory.mktemp("failing"),
                                needsExecutionTool="false")


@pytest.mark.pythonfmu
@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_run_failing_half_way_leaves_its_rows_readable(tmp_path, built_fmus, failing_fmu, suffix, capsys):
    """Failing.fmu refuses the step from t = 5 s (fmi2Fatal); 5001 rows, more than one 4096-row chunk."""
    components = {"f": ("Failing.fmu", {"u": "input", "y": "output"}),
                  "lag": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("failing", components, [("f", "y", "lag", "u")], stop=10.0, step=0.001,
                    parameters={"f": {"fail_time": 5.0}})
    folder = write_system(tmp_path / "sys", {"Failing.fmu": failing_fmu,
                                             "FirstOrderFilter.fmu": built_fmus["FirstOrderFilter"]}, text)
    output = tmp_path / f"out{suffix}"
    assert main(["run", str(folder), "-q", "-o", str(output)]) == 1
    assert "fmi2DoStep returned Fatal at t = 5" in capsys.readouterr().err
    if suffix == ".csv":
        result = read(output)
        time, y = result["time"], result["f.y"]
    else:
        parquet = pq.ParquetFile(output)
        assert parquet.metadata.num_row_groups == 2
        table = parquet.read()
        time, y = table.column("time").to_numpy(), table.column("f.y").to_numpy()
        assert json.loads(pq.read_metadata(output).metadata[b"cosim"])["status"] == "failed"
    assert len(time) == 5001 and time[-1] == pytest.approx(5.0) and y[-1] == pytest.approx(5.0)
    assert json.loads(output.with_suffix(".json").read_text())["status"] == "failed"
