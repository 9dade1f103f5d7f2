"""Results on disk: read and write result files (CSV, Parquet), and choose signals of a result by
name (`select`); `cosim.present.plots` draws them."""
from __future__ import annotations

import fnmatch
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import SetupError, did_you_mean
from ..extras import require_pyarrow


def read(path: str | Path) -> np.ndarray:
    """Read a result file into a structured array (``fmpy.util.read_csv`` format): a
    ``.parquet`` file written by `cosim.record.observers.ParquetSink`, else a result CSV.  A missing
    or unreadable file is a `SetupError` naming it."""
    if not Path(path).is_file():
        raise SetupError("no such result file.", file=str(path))
    if Path(path).suffix.lower() == ".parquet":
        require_pyarrow("reading a Parquet result", file=str(path))
    try:
        result = _read_parquet(path) if Path(path).suffix.lower() == ".parquet" else _read_csv(path)
    except (ValueError, IndexError, TypeError, UnicodeDecodeError) as e:  # pyarrow's ArrowInvalid is a ValueError
        raise SetupError(f"not a result file (a CSV readable by fmpy.util.read_csv, or Parquet) ({e}).",
                         file=str(path)) from None
    names = result.dtype.names or ()
    if "time" not in names:
        raise SetupError(f"the result has no 'time' column (columns: {', '.join(names[:8]) or 'none'}).",
                         file=str(path))
    time = result["time"]
    if not (np.isfinite(time).all() and (np.diff(time) >= 0).all()):
        raise SetupError("the 'time' column is not finite and non-decreasing.", file=str(path))
    return result


def _read_parquet(path: str | Path) -> np.ndarray:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    result = np.empty(table.num_rows, dtype=[(name, np.float64) for name in table.column_names])
    for name in table.column_names:
        result[name] = table.column(name).to_numpy()
    return result


def _read_csv(path: str | Path) -> np.ndarray:
    """A CSV as ``fmpy.util.read_csv`` reads it (one float per field, or a space-separated
    vector of them, the first row giving each column's shape), with its header parsed as RFC
    4180 says (`cosim.record.observers.csv_header`: quoted names may hold commas, ``""`` and line
    breaks).  A vector column (an FMI 3.0 array as fmusim and ``fmpy.util.write_csv`` write it)
    is read as one column per value, ``y[1]`` .. ``y[n]``, the names a run records a
    one-dimensional array's elements by (`cosim.model.fmu.element_names`)."""
    import csv
    import io

    source = io.StringIO(Path(path).read_text(encoding="utf-8"), newline="")
    names = next(csv.reader(source), None)
    lines = source.read().splitlines()
    if names is None or not lines:
        raise ValueError("no header and row")
    widths = [len(field.split(" ")) for field in lines[0].split(",")]
    columns = [(element, np.float64) for name, n in zip(names, widths)
               for element in ([f"{name}[{k}]" for k in range(1, n + 1)] if n > 1 else [name])]
    rows = [tuple(float(v) for field in line.split(",") for v in field.split(" ")) for line in lines]
    return np.array(rows, dtype=np.dtype(columns))


def write(result: np.ndarray, path: str | Path, names: Sequence[str] | None = None) -> Path:
    """Write ``time`` and the named fields (default: all) as `cosim.record.observers.file_sink` writes
    a run (CSV, or Parquet for a ``.parquet`` name: every float64 reads back bit for bit),
    without the metadata JSON a run writes beside it; the file is replaced in one rename."""
    from .observers import file_sink

    path = Path(path)
    columns = ["time"] + [n for n in (names if names is not None else result.dtype.names) if n != "time"]
    sink = file_sink(path)
    sink.open(columns)
    if len(result):
        sink.write(np.column_stack([result[n] for n in columns]))
    sink.finish()
    sink.publish(None)
    return path


def matches(name: str, pattern: str) -> bool:
    """Whether a signal name matches a glob: ``*`` and ``?`` as in `fnmatch`, brackets literal (they
    index FMI 3.0 array elements: ``A[2,3]`` names one, ``A[*]`` them all)."""
    return fnmatch.fnmatchcase(name, pattern.replace("[", "[[]"))


def panel(text: str) -> list[str]:
    """The globs of one ``--signals`` panel: ``a,b`` overlays a and b; a comma inside brackets
    (``A[2,3]``) separates nothing."""
    return re.split(r",(?![^\[]*\])", text)


def select(names: Sequence[str], patterns: Sequence[str], option: str = "--signals") -> list[str]:
    """Names matching any glob pattern (`matches`), in the order of ``names``; an unmatched pattern is
    an error naming the ``option`` it was given with."""
    chosen = []
    for pattern in patterns:
        matched = [n for n in names if matches(n, pattern)]
        if not matched:
            raise SetupError(f"no signal matches '{pattern}'.", element=option,
                             hint=did_you_mean(pattern, names) or f"Signals: {', '.join(names[:12])}.")
        chosen += [n for n in matched if n not in chosen]
    return chosen
