"""Result CSV rows as text, without Arrow: the bytes pyarrow's CSV writer writes for float64 columns.

Each float64 is written in the shortest decimal form that reads back to the same bits (the digits
of Python's ``repr``), laid out as Arrow's writer lays it out (double-conversion's "shortest"
mode): positional notation for a decimal exponent from -6 to 9 (``0.000001``, ``1250000000``, no
trailing ``.0``), else exponential with a signed exponent of no leading zero (``1e-7``,
``1.25e+10``); ``-0``, ``inf``, ``-inf`` and ``nan`` (whatever its sign) as such.

`format_rows` formats them in C (``cosim/kernel/csvrows.c``: Ryu's shortest digits, laid out as
here) when the compiled kernel library was built with greyfmu (`cosim.kernel.library`), else with
`format_rows_python`, the same bytes at about 9x the cost per value (benchmarks/bench_csv.py:
C 0.53x Arrow's writer, Python 5x); `RowText` makes the same text block by block into a buffer
it keeps (a result file's chunks, `cosim.record.observers.CsvSink`).

`format_rows_python` makes the row text by one ``%`` formatting of the whole chunk (``repr`` of
every value, in C); the values of the two ranges where ``repr`` and Arrow choose different notations (about 1e-6 and
1e10..1e15, rare in a run's signals) are formatted one by one first (`format_float`), then two
regular expressions rewrite what is left: the ``.0`` of a whole number and the zero-padded
exponent (``e-07``).
"""
from __future__ import annotations

import re
from collections.abc import Iterator

import numpy as np

from .. import kernel

#: decimal exponents written in positional notation (double-conversion's decimal_in_shortest_low/high)
_POSITIONAL = range(-6, 10)
#: magnitudes where ``repr`` and Arrow choose different notations: ``repr`` writes 1e-06 and 1e-05
#: exponential and 1e10..1e15 positional (bounds taken wide: `format_float` is right for any value)
_DIFFERENT_NOTATION = ((1e-7, 1e-4), (1e9, 1e17))
#: the ``.0`` of a whole number written by ``repr``
_WHOLE = re.compile(r"\.0(?=[,\n])")
#: ``repr``'s zero-padded exponent
_PADDED_EXPONENT = re.compile(r"e([+-])0(?=\d)")


class _Verbatim(str):
    """A text that ``%r`` writes as it is."""

    def __repr__(self) -> str:
        return str(self)


def format_float(x: float) -> str:
    """One float64 as Arrow's CSV writer writes it."""
    if x != x:
        return "nan"
    text = repr(float(x))
    if text in ("inf", "-inf"):
        return text
    sign = "-" if text.startswith("-") else ""
    text = text.lstrip("-")
    mantissa, _, exponent = text.partition("e")
    whole, _, fraction = mantissa.partition(".")
    digits = (whole + fraction).lstrip("0")
    if not digits:
        return sign + "0"
    # value = 0.DIGITS x 10^point
    point = len(whole) + int(exponent or 0) if whole != "0" else int(exponent or 0) - (len(fraction) - len(fraction.lstrip("0")))
    digits = digits.rstrip("0")
    return sign + _layout(digits, point)


def _layout(digits: str, point: int) -> str:
    """The text of 0.``digits`` x 10^``point`` (``digits`` with no leading or trailing zero)."""
    exponent = point - 1
    if exponent in _POSITIONAL:
        if point <= 0:
            return "0." + "0" * -point + digits
        if point >= len(digits):
            return digits + "0" * (point - len(digits))
        return digits[:point] + "." + digits[point:]
    tail = "." + digits[1:] if len(digits) > 1 else ""
    return f"{digits[0]}{tail}e{'+' if exponent >= 0 else '-'}{abs(exponent)}"


#: bytes of text `RowText` formats at a time, into one buffer it keeps
TEXT_BLOCK = 1 << 20


class RowText:
    """The lines of 2-D float64 arrays of ``columns`` columns, made block by block into one
    buffer kept across calls (a result file's chunks: no text the size of a chunk, and no new
    buffer per chunk); in C if the kernel library is built, else by `format_rows_python`."""

    def __init__(self, columns: int):
        self._lib, _ = kernel.library()
        if self._lib is not None:
            per_row = max(1, columns) * self._lib.cosim_csv_value_max()
            self._rows = max(1, TEXT_BLOCK // per_row)
            self._out = np.empty(self._rows * per_row, dtype=np.uint8)

    def blocks(self, rows: np.ndarray) -> Iterator[bytes | memoryview]:
        """The text of ``rows`` in blocks (a block is valid until the next one is asked for)."""
        if self._lib is None:
            yield format_rows_python(rows).encode()
            return
        for start in range(0, len(rows), self._rows):
            part = np.ascontiguousarray(rows[start:start + self._rows], dtype=np.float64)
            length = self._lib.cosim_format_rows(part.ctypes.data, len(part), part.shape[1], self._out.ctypes.data)
            yield memoryview(self._out)[:length]


def format_rows(rows: np.ndarray) -> bytes:
    """The lines of a 2-D float64 array, comma-separated, each ending in ``\\n`` (none for no
    rows), formatted in C if the kernel library is built, else by `format_rows_python`."""
    return b"".join(bytes(block) for block in RowText(rows.shape[1]).blocks(rows))


def format_rows_python(rows: np.ndarray) -> str:
    """`format_rows` in Python (``repr`` of every value, rewritten to Arrow's layout)."""
    count, columns = rows.shape
    if count == 0 or columns == 0:
        return ""
    values = rows.ravel().tolist()
    size = np.abs(rows.ravel())
    other = np.zeros(len(values), dtype=bool)
    for low, high in _DIFFERENT_NOTATION:
        other |= (size >= low) & (size < high)
    for i in np.flatnonzero(other).tolist():
        values[i] = _Verbatim(format_float(values[i]))
    text = ((",".join(("%r",) * columns) + "\n") * count) % tuple(values)
    return _PADDED_EXPONENT.sub(r"e\1", _WHOLE.sub("", text))
