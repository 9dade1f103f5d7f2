"""The sweep's results table: one row per run, written as ``sweep.csv`` (always) and
``sweep.parquet`` (when pyarrow, the ``parquet`` extra, is installed), replaced atomically as runs
finish, and read back from ``sweep.csv`` to skip finished runs.

``sweep.csv`` is written here, not by Arrow, in the bytes Arrow's CSV writer gives the same typed
table (so it is the same file with or without pyarrow): RFC 4180, a quoted header, strings
always quoted (``"`` doubled), a missing value (null) as an empty unquoted field, floats as
`cosim.record.csvformat.format_float` writes them, integers in decimal, booleans ``true``/``false``.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..record.csvformat import format_float
from ..errors import SetupError
from ..extras import has_pyarrow, require_pyarrow
from ..safeio import atomic_path, write_atomic
from .values import Metric

#: column type (Arrow's alias) of a swept column per FMI variable type
_TYPES = {"Real": "float64", "Integer": "int64", "Boolean": "bool", "String": "string"}
#: Statuses whose results are kept and not run again
FINISHED = ("completed", "discarded")
#: one CSV field at the start of the text: quoted (group 1, ``""`` for ``"``) or not (group 2)
_FIELD = re.compile(r'"((?:[^"]|"")*)"|([^,"\n]*)')


@dataclass(frozen=True)
class Schema:
    """The table's columns, in order: (name, type), the type one of ``string``, ``float64``,
    ``int64``, ``bool``."""
    columns: tuple[tuple[str, str], ...]

    @property
    def names(self) -> list[str]:
        return [name for name, _ in self.columns]

    def arrow(self):
        """The same schema for pyarrow."""
        import pyarrow as pa
        return pa.schema([(name, pa.type_for_alias(kind)) for name, kind in self.columns])


def schema_of(swept: Mapping[str, str], seeded: bool, metrics: Sequence[Metric]) -> Schema:
    columns = [("run_id", "string")]
    columns += [(name, _TYPES[t]) for name, t in swept.items()]
    columns += [("seed", "int64")] if seeded else []
    columns += [("status", "string"), ("message", "string"), ("error", "string"), ("wall_time", "float64")]
    columns += [(c, "float64") for m in metrics for c in m.columns()]
    columns += [(m.reason_column(), "string") for m in metrics]
    return Schema(tuple(columns))


def _quoted(text: str) -> str:
    return '"' + text.replace('"', '""') + '"'


def _field(value: Any, kind: str) -> str:
    if value is None:
        return ""
    if kind == "string":
        return _quoted(str(value))
    if kind == "float64":
        return format_float(float(value))
    if kind == "bool":
        return "true" if value else "false"
    return str(int(value))


def csv_text(rows: Sequence[Mapping[str, Any]], schema: Schema) -> str:
    """``sweep.csv``'s text: the columns of ``schema`` (a row's other keys left out, a missing
    key a null)."""
    lines = [",".join(_quoted(name) for name in schema.names)]
    lines += [",".join(_field(row.get(name), kind) for name, kind in schema.columns) for row in rows]
    return "\n".join(lines) + "\n"


def write_table(rows: list[dict[str, Any]], schema: Schema, csv: Path, parquet: Path) -> None:
    """``sweep.csv``, then ``sweep.parquet`` if pyarrow is installed, each replaced atomically, so
    a reader or a crash never sees half a table."""
    write_atomic(csv, csv_text(rows, schema))
    if has_pyarrow():
        import pyarrow as pa
        import pyarrow.parquet as pq

        with atomic_path(parquet) as part:
            pq.write_table(pa.Table.from_pylist(rows, schema=schema.arrow()), part)


def _csv_records(text: str, path: Path) -> list[list[str | None]]:
    """The records of an RFC 4180 text as written by `csv_text`: a quoted field as its text, an
    empty unquoted one as None."""
    records, record, at = [], [], 0
    while at < len(text):
        match = _FIELD.match(text, at)
        quoted, plain = match.groups()
        record.append(quoted.replace('""', '"') if quoted is not None else (plain or None))
        at = match.end()
        end = text[at:at + 1]
        if end not in (",", "\n"):
            raise ValueError(f"line {len(records) + 1}: {end!r} after field {len(record)} of {path}")
        at += 1
        if end == "\n":
            records.append(record)
            record = []
    if record:
        raise ValueError(f"{path} does not end with a line break")
    return records


def _typed(text: str | None, kind: str) -> Any:
    if text is None or kind == "string":
        return text
    if kind == "float64":
        return float(text)
    if kind == "bool":
        return {"true": True, "false": False}[text]
    return int(text)


def read_table(path: str | Path, schema: Schema | None = None) -> list[dict[str, Any]]:
    """The rows of a sweep table: ``sweep.parquet`` (typed; needs pyarrow) or ``sweep.csv``, its
    columns typed as ``schema`` types them (columns it does not name left out; without a schema
    every value is its text, a null None)."""
    path = Path(path)
    if path.suffix == ".parquet":
        require_pyarrow("reading a sweep's Parquet table", file=str(path))
        import pyarrow.parquet as pq
        return pq.read_table(path).to_pylist()
    with open(path, encoding="utf-8", newline="") as file:    # a quoted field's \r kept as written
        records = _csv_records(file.read(), path)
    if not records:
        raise ValueError(f"{path} is empty (no header)")
    header, *records = records
    for line, record in enumerate(records, start=2):
        if len(record) != len(header):
            raise ValueError(f"line {line} of {path} has {len(record)} fields, its header {len(header)}")
    kinds = dict(schema.columns) if schema is not None else dict.fromkeys(header, "string")
    return [{name: _typed(text, kinds[name]) for name, text in zip(header, record) if name in kinds}
            for record in records]


def finished_before(output: Path, runs_dir: Path, schema: Schema) -> dict[str, dict[str, Any]]:
    """Rows of an earlier sweep into this folder (its ``sweep.csv``, typed as ``schema``) whose
    results are still on disk."""
    csv = output / "sweep.csv"
    if not csv.is_file():
        return {}
    try:
        rows = read_table(csv, schema)
    except (ValueError, KeyError, UnicodeDecodeError) as e:
        raise SetupError(f"cannot read the earlier sweep table ({e}); delete it or pass --force.",
                         file=str(csv)) from None
    return {r["run_id"]: r for r in rows if r.get("status") in FINISHED
            and (runs_dir / f"{r['run_id']}.csv").is_file() and (runs_dir / f"{r['run_id']}.json").is_file()}
