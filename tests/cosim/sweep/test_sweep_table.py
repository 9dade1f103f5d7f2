"""Issue 27: a sweep's ``sweep.csv`` is written by cosim (`cosim.sweep.table.csv_text`) in the bytes
pyarrow's CSV writer gives the same typed table, and read back typed (`read_table`), so a sweep
needs no pyarrow."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cosim.sweep.table import Schema, csv_text, read_table, schema_of
from cosim.sweep.values import Metric

pa = pytest.importorskip("pyarrow")
import pyarrow.csv as pacsv  # noqa: E402

SCHEMA = Schema((("run_id", "string"), ("g.k", "float64"), ("g.n", "int64"), ("g.on", "bool"),
                 ("message", "string"), ("wall_time", "float64")))
STRINGS = ['plain', 'with "quotes"', 'a,b', 'two\nlines', 'cr\r\nlf', '', ' lead and trail ', 'é ü ∞', '"', '""',
           'x\n']
FLOATS = [0.0, -0.0, 1.0, -2.5, 0.1, 1e-7, 1e-6, 1e-5, 1e22, 1e15, 1e10, 123456789012.0, 5e-324,
          1.7976931348623157e308, math.inf, -math.inf, math.nan, 1 / 3]
INTS = [0, -1, 7, 2**62, -(2**63)]


def _arrow_csv(rows: list[dict], schema: Schema) -> str:
    """What pyarrow's CSV writer (the writer of ``sweep.csv`` before issue 27) writes for ``rows``."""
    sink = pa.BufferOutputStream()
    pacsv.write_csv(pa.Table.from_pylist(rows, schema=schema.arrow()), sink)
    return sink.getvalue().to_pybytes().decode("utf-8")


def _rows() -> list[dict]:
    rows = []
    for i in range(max(len(STRINGS), len(FLOATS), len(INTS))):
        rows.append({"run_id": STRINGS[i % len(STRINGS)], "g.k": FLOATS[i % len(FLOATS)], "g.n": INTS[i % len(INTS)],
                     "g.on": i % 2 == 0, "message": STRINGS[(i + 3) % len(STRINGS)],
                     "wall_time": FLOATS[(i + 5) % len(FLOATS)]})
    rows.append({name: None for name in SCHEMA.names})          # a null in every type
    rows.append({"run_id": "only an id"})                        # missing keys are nulls
    return rows


def _same(a, b) -> bool:
    return (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)) or \
        (a == b and type(a) is type(b) and (not isinstance(a, float) or math.copysign(1, a) == math.copysign(1, b)))


def test_sweep_csv_has_the_bytes_of_arrow_s_writer(tmp_path):
    rows = _rows()
    text = csv_text(rows, SCHEMA)
    assert text == _arrow_csv(rows, SCHEMA)
    assert csv_text([], SCHEMA) == _arrow_csv([], SCHEMA) == '"run_id","g.k","g.n","g.on","message","wall_time"\n'
    path = tmp_path / "sweep.csv"
    path.write_bytes(text.encode("utf-8"))
    back = read_table(path, SCHEMA)
    full = [{name: row.get(name) for name in SCHEMA.names} for row in rows]
    assert len(back) == len(full)
    for got, want in zip(back, full):
        assert all(_same(got[name], want[name]) for name in SCHEMA.names), (got, want)


def test_a_real_sweep_schema_with_metrics_matches_arrow(tmp_path):
    metric = Metric("plant.y", "setpoint.y")
    schema = schema_of({"c.Kc": "Real", "c.mode": "Integer", "c.on": "Boolean", "c.name": "String"}, True, [metric])
    rows = [{"run_id": "9f2c", "c.Kc": 4.0, "c.mode": 3, "c.on": True, "c.name": 'a "b", c', "seed": 1,
             "status": "completed", "message": None, "wall_time": 0.4771591039999521,
             **{c: 1e-7 * k for k, c in enumerate(metric.columns())},
             metric.reason_column(): "settling_time: the response is still outside ±2 %\nat 140 s"},
            {"run_id": "0a1b", "c.Kc": 6.0, "c.mode": 1, "c.on": False, "c.name": "", "seed": 2, "status": "failed",
             "message": "plant: fmi2DoStep returned fmi2Error at t = 3.0", "error": "model_error", "wall_time": 0.02}]
    assert csv_text(rows, schema) == _arrow_csv(rows, schema)


def test_a_damaged_table_is_refused_naming_its_line(tmp_path):
    path = tmp_path / "sweep.csv"
    path.write_text('"run_id","wall_time"\n"a",1\n"b"x,2\n')
    with pytest.raises(ValueError, match="line 3: 'x' after field 1"):
        read_table(path, Schema((("run_id", "string"), ("wall_time", "float64"))))
    path.write_text('"run_id","wall_time"\n"a"\n')
    with pytest.raises(ValueError, match="line 2 of .* has 1 fields, its header 2"):
        read_table(path)
    path.write_text("")
    with pytest.raises(ValueError, match="is empty"):
        read_table(path)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.one_of(st.none(), st.text()), st.one_of(st.none(), st.floats()),
                          st.one_of(st.none(), st.integers(-(2**63), 2**63 - 1)), st.one_of(st.none(), st.booleans())),
                max_size=5))
def test_random_tables_have_the_bytes_of_arrow_s_writer(values):
    schema = Schema((("s", "string"), ("f", "float64"), ("i", "int64"), ("b", "bool")))
    rows = [dict(zip(schema.names, row)) for row in values]
    assert csv_text(rows, schema) == _arrow_csv(rows, schema)
