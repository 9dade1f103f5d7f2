"""Optional dependencies (issue 27): what needs an extra of greyfmu, and the message naming it.

pyarrow (``pip install 'greyfmu[parquet]'``, about 170 MB) writes and reads Parquet results and
a sweep's ``sweep.parquet``; CSV results and sweeps (their ``sweep.csv``, `cosim.sweep.table`)
need nothing more, and with pyarrow are the same bytes (`cosim.record.observers.CsvSink`).
"""
from __future__ import annotations

import importlib.util

from .errors import SetupError

#: the pip command that installs pyarrow with greyfmu
PARQUET_EXTRA = "pip install 'greyfmu[parquet]'"


def has_pyarrow() -> bool:
    """Whether pyarrow can be imported (found, not imported: importing it takes a while)."""
    return importlib.util.find_spec("pyarrow") is not None


def require_pyarrow(what: str, *, file: str | None = None, element: str | None = None) -> None:
    """A `SetupError` (exit status 2) naming the extra to install when pyarrow is missing."""
    if not has_pyarrow():
        raise SetupError(f"{what} needs pyarrow, which is not installed; install it with {PARQUET_EXTRA} "
                         "(in a clone: pip install -e '.[parquet]'), or write a CSV (a .csv name).",
                         file=file, element=element)
