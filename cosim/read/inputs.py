"""Input tables (``--input-file``) as read: a CSV that drives inputs by name, as ``fmpy simulate``
reads it.

The file is fmpy's format: a header row whose first column is ``time``, then one column per
input, one row per sample, times non-decreasing.  A time written on two rows is an event: the
first row is the value just before it, the last the value from then on.  `cosim.plan.inputs`
binds the columns to a plan's inputs and `cosim.run.feed` sets their values during a run.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
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
    data = np.empty((len(rows) - 1, len(names)))
    lines = []
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise SetupError(f"{len(row)} cells; the header has {len(names)} columns.", file=file,
                             element=f"line {line}")
        for c, cell in enumerate(row):
            data[r, c] = _number(cell, file, line, names[c])
        if r and data[r, 0] < data[r - 1, 0]:
            raise SetupError(f"time {data[r, 0]:.17g} is before the time of the row before ({data[r - 1, 0]:.17g}); "
                             "times must not decrease (a time given twice is an event).", file=file,
                             element=f"line {line}, column 'time'")
        lines.append(line)
    return InputTable(file, names[1:], data[:, 0].copy(), data[:, 1:].T.copy(), lines)


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
