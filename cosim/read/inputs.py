"""Input tables (``--input-file``) as read: a CSV that drives inputs by name, as ``fmpy simulate``
reads it.

The file is fmpy's format: a header row whose first column is ``time``, then one column per
input, one row per sample, times non-decreasing.  A time written on two rows is an event: the
first row is the value just before it, the last the value from then on.  A cell may hold an FMI
3.0 array's values separated by spaces, as fmusim and ``fmpy.util.write_csv`` write them
(``u`` = ``1 2``): the column is read as one column per value, in the array's order (row-major).
`cosim.plan.inputs` binds the columns to a plan's inputs and `cosim.run.feed` sets their values
during a run.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SetupError


@dataclass(frozen=True)
class InputTable:
    """A CSV input table as read: column names (after ``time``), sample times and values."""
    file: str
    names: list[str]
    time: np.ndarray
    #: one row per column, one entry per sample
    values: np.ndarray
    #: the line of the file each sample is on (for messages)
    lines: list[int]
    #: the columns whose cells hold several values (an array's, `read_input_table`): each read as
    #: columns ``name[1]`` .. ``name[n]`` numbered by position, n by name
    arrays: dict[str, int] = field(default_factory=dict)


def read_input_table(path: str | Path) -> InputTable:
    """Read and check an input CSV; a missing file, a header without ``time`` first, a repeated
    column, a row of the wrong length, a cell that is not a finite number (or true/false) and a
    time before the previous one are each a `SetupError` naming the file, column and line."""
    file = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = [(n, row) for n, row in enumerate(csv.reader(f), 1) if row and any(c.strip() for c in row)]
    except OSError as e:
        raise SetupError(f"cannot read the input table: {e.strerror}.", file=file, element="--input-file") from None
    except (UnicodeDecodeError, csv.Error) as e:
        raise SetupError(f"not a CSV text file: {e}.", file=file, element="--input-file") from None
    if not rows:
        raise SetupError("the input table is empty; it needs a header row (time, then input names) and samples.",
                         file=file, element="--input-file")
    header_line, header = rows[0]
    names = [h.strip() for h in header]
    if names[0] != "time":
        raise SetupError(f"the first column is '{names[0]}'; an input table's first column is 'time'.",
                         file=file, element=f"line {header_line}, column 1")
    for i, name in enumerate(names):
        if not name:
            raise SetupError(f"column {i + 1} has no name.", file=file, element=f"line {header_line}")
        if names.index(name) != i:
            raise SetupError(f"column '{name}' is given twice (columns {names.index(name) + 1} and {i + 1}).",
                             file=file, element=f"line {header_line}", variable=name)
    if len(rows) < 2:
        raise SetupError("the input table has a header and no samples.", file=file, element="--input-file")
    widths = [len(cell.split()) for cell in rows[1][1]] if len(rows[1][1]) == len(names) else []
    arrays = {name: n for name, n in zip(names[1:], widths[1:]) if n > 1}
    columns = [f"{name}[{k}]" for name in names[1:] for k in range(1, arrays.get(name, 1) + 1)
               ] if arrays else names[1:]
    twice = next((f"{a}[{k}]" for a, n in arrays.items() for k in range(1, n + 1) if f"{a}[{k}]" in names), None)
    if twice is not None:   # 'u' with 2 values per row and a column 'u[1]'
        raise SetupError(f"column '{twice}' is given twice (alone, and as a value of the array column "
                         f"'{twice.partition('[')[0]}').", file=file, element=f"line {header_line}", variable=twice)
    data = np.empty((len(rows) - 1, len(columns) + 1))
    lines = []
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise SetupError(f"{len(row)} cells; the header has {len(names)} columns.", file=file,
                             element=f"line {line}")
        c = 0
        for name, cell in zip(names, row):
            width = arrays.get(name, 1)
            values = cell.split() if name in arrays else [cell]
            if len(values) != width:
                raise SetupError(f"{len(values)} values in the cell; the array column '{name}' has {width} per row "
                                 f"(line {rows[1][0]}).", file=file, element=f"line {line}, column '{name}'",
                                 variable=name)
            for value in values:
                data[r, c] = _number(value, file, line, name)
                c += 1
        if r and data[r, 0] < data[r - 1, 0]:
            raise SetupError(f"time {data[r, 0]:.17g} is before the time of the row before ({data[r - 1, 0]:.17g}); "
                             "times must not decrease (a time given twice is an event).", file=file,
                             element=f"line {line}, column 'time'")
        lines.append(line)
    return InputTable(file, columns, data[:, 0].copy(), data[:, 1:].T.copy(), lines, arrays)


def _number(cell: str, file: str, line: int, column: str) -> float:
    text = cell.strip()
    if text.lower() in ("true", "false"):
        return 1.0 if text.lower() == "true" else 0.0
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SetupError(f"'{cell}' is not a finite number.", file=file, element=f"line {line}, column '{column}'",
                         variable=column)
    return value
