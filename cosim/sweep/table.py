"""The sweep's results table: one row per run, written as ``sweep.csv`` and ``sweep.parquet``
(replaced atomically as runs finish), and read back to skip finished runs."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..errors import SetupError
from ..safeio import atomic_path
from .values import Metric

#: Arrow type of a swept column per FMI variable type
_ARROW_TYPES = {"Real": "float64", "Integer": "int64", "Boolean": "bool", "String": "string"}
#: Statuses whose results are kept and not run again
FINISHED = ("completed", "discarded")


def schema_of(swept: Mapping[str, str], seeded: bool, metrics: Sequence[Metric]):
    import pyarrow as pa

    fields = [("run_id", pa.string())]
    fields += [(name, pa.type_for_alias(_ARROW_TYPES[t])) for name, t in swept.items()]
    fields += [("seed", pa.int64())] if seeded else []
    fields += [("status", pa.string()), ("message", pa.string()), ("wall_time", pa.float64())]
    fields += [(c, pa.float64()) for m in metrics for c in m.columns()]
    fields += [(m.reason_column(), pa.string()) for m in metrics]
    return pa.schema(fields)


def write_table(rows: list[dict[str, Any]], schema, csv: Path, parquet: Path) -> None:
    """Both files replaced atomically, so a reader or a crash never sees half a table."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=schema)
    for path, write in ((parquet, pq.write_table), (csv, pacsv.write_csv)):
        with atomic_path(path) as part:
            write(table, part)


def read_table(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a sweep table (``sweep.parquet``, typed)."""
    import pyarrow.parquet as pq
    return pq.read_table(path).to_pylist()


def finished_before(output: Path, runs_dir: Path) -> dict[str, dict[str, Any]]:
    """Rows of an earlier sweep into this folder whose results are still on disk."""
    parquet = output / "sweep.parquet"
    if not parquet.is_file():
        return {}
    try:
        rows = read_table(parquet)
    except Exception as e:  # noqa: BLE001 -- pyarrow raises several types for a damaged file
        raise SetupError(f"cannot read the earlier sweep table ({e}); delete it or pass --force.",
                         file=str(parquet)) from None
    return {r["run_id"]: r for r in rows if r.get("status") in FINISHED
            and (runs_dir / f"{r['run_id']}.csv").is_file() and (runs_dir / f"{r['run_id']}.json").is_file()}
