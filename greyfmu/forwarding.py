"""Hand greyfmu's warnings to a host's log: the FMU-log bridge's greyfmu half (no FMI here).

greyfmu reports fallbacks two ways: ``logging`` warnings under the ``greyfmu`` logger (a NaN
measurement held, an infeasible QP, a refused scheduling variable) and Python ``warnings`` (an
off-line design outside the paper's advice, ``HorizonWarning``).  ``forward_warnings(emit)``
passes both to ``emit(message)`` while its block runs; the slave base (fmus/_slave.py) wraps
``build``, ``advance`` and a tunable parameter's retune in it, so every FMU forwards them to its
own FMU logger (fmi2Warning) and only the instance that caused a warning reports it.
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Callable, Iterator

LOGGER = logging.getLogger(__name__.rpartition(".")[0])
"""greyfmu's package logger, under the name this copy of greyfmu is imported as (inside an FMU, its
private package's ``<package>.greyfmu``, greyfmu.privatise: each FMU forwards its own numerics' warnings)."""


class _Emit(logging.Handler):
    def __init__(self, emit: Callable[[str], None]) -> None:
        super().__init__(logging.WARNING)
        self._emit = emit

    def emit(self, record: logging.LogRecord) -> None:
        self._emit(record.getMessage())


@contextlib.contextmanager
def forward_warnings(emit: Callable[[str], None]) -> Iterator[None]:
    """While the block runs, ``emit`` each greyfmu log record of level WARNING or above as it is
    logged, and each Python warning raised in the block (every occurrence) when the block ends."""
    handler = _Emit(emit)
    LOGGER.addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                yield
            finally:
                for warning in caught:
                    emit(str(warning.message))
    finally:
        LOGGER.removeHandler(handler)
