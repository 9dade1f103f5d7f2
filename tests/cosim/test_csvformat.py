"""Issue 27: a result CSV written without pyarrow has the bytes pyarrow's writer gives it."""
import numpy as np
import pytest

from cosim import kernel

from cosim.record import observers
from cosim.record.csvformat import format_float, format_rows, format_rows_python
from cosim.record.observers import CsvSink

pytest.importorskip("pyarrow")


def _values() -> np.ndarray:
    """Random bit patterns, every decade's edges and the special values."""
    rng = np.random.default_rng(27)
    edges = [s * m * 10.0 ** k for k in range(-320, 308) for m in (1, 1.25, 9.999999999999999, 3.3333333333333335)
             for s in (1, -1)]
    special = [0.0, -0.0, np.inf, -np.inf, np.nan, -np.nan, 5e-324, 1.7976931348623157e308, 0.1, 1e15, 1e-5]
    return np.concatenate([rng.integers(0, 2**64, size=40000, dtype=np.uint64).view(np.float64), edges, special,
                           rng.normal(size=4000) * 1e-5, np.round(rng.normal(size=4000) * 1e6),
                           np.cumsum(rng.normal(size=4000))])


def _arrow_rows(rows: np.ndarray) -> bytes:
    """The lines Arrow's CSV writer writes for ``rows`` (the writer of a result CSV before issue 27)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    table = pa.Table.from_arrays(list(np.ascontiguousarray(rows.T)), names=[str(i) for i in range(rows.shape[1])])
    sink = pa.BufferOutputStream()
    pcsv.write_csv(table, sink, pcsv.WriteOptions(include_header=False))
    return sink.getvalue().to_pybytes()


def test_compiled_rows_equal_arrow_rows():
    assert kernel.library()[0] is not None, kernel.library()[1]   # else format_rows is the Python one
    values = _values()
    rows = values[: len(values) // 5 * 5].reshape(-1, 5)
    assert format_rows(rows) == _arrow_rows(rows)
    assert format_rows(rows[::-1, ::2]) == _arrow_rows(rows[::-1, ::2])   # not C-contiguous
    assert format_rows(rows[:0]) == b"" and _arrow_rows(rows[:0]) == b""


def test_python_rows_equal_arrow_rows():
    values = _values()
    rows = values[: len(values) // 5 * 5].reshape(-1, 5)
    assert format_rows_python(rows).encode() == _arrow_rows(rows)
    assert format_rows_python(rows[:0]) == "" and _arrow_rows(rows[:0]) == b""


@pytest.mark.parametrize("value, text", [(1.0, "1"), (-0.0, "-0"), (1e-7, "1e-7"), (1e-5, "0.00001"),
                                         (1e10, "1e+10"), (1234567890.0, "1234567890"), (0.1, "0.1"),
                                         (-np.nan, "nan"), (-np.inf, "-inf"), (123456789012345.6, "1.234567890123456e+14")])
def test_format_float(value, text):
    assert format_float(value) == text


def test_csv_file_bytes_equal_with_and_without_pyarrow(tmp_path, monkeypatch):
    """The whole file (the RFC 4180 quoted header, every row at full precision) is the same."""
    names = ["time", 'a "quoted", name', "b\nline"]
    rows = _values()[:3000].reshape(-1, 3)
    files = {}
    for kind, arrow in (("arrow", True), ("python", False)):
        monkeypatch.setattr(observers, "ARROW_CSV", arrow)
        sink = CsvSink(tmp_path / f"{kind}.csv")
        sink.open(names)
        sink.write(rows[:500])
        sink.write(rows[500:])
        sink.close({})
        files[kind] = (tmp_path / f"{kind}.csv").read_bytes()
    assert files["python"] == files["arrow"]
    assert files["python"].startswith(b'"time","a ""quoted"", name","b\nline"\n')
