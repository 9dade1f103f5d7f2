"""What a run ended with (issue 29): the value `cosim.run.simulation.run` returns, and that a run
which failed half way hands on with its exception (``error.run_outcome``), so nothing recorded
before the failure is lost.  Callers (the CLI, a sweep's worker, `cosim.run.simulation.simulate`) read it; no
one writes the execution's status or edits an error's text to report a run.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import Errc


@dataclass(frozen=True)
class RunOutcome:
    """How a run ended: ``status`` (completed, terminated, discarded, interrupted, timeout,
    failed, crashed), its ``message``, the `Errc` of a failure (None otherwise), the samples
    kept in memory (``result``: None when a failure left no memory to join them), the result
    file (``output``, None for a run to memory) and the ``metadata`` written beside it."""

    status: str
    message: str
    error: Errc | None
    result: np.ndarray | None
    output: Path | None
    metadata: dict[str, Any]

    @classmethod
    def of(cls, metadata: dict[str, Any], result: np.ndarray | None, output: str | Path | None) -> RunOutcome:
        """The outcome a run's ``metadata`` records (its status, message and error code)."""
        return cls(metadata["status"], metadata["message"],
                   Errc(metadata["error"]) if metadata["error"] is not None else None,
                   result, Path(output) if output is not None else None, metadata)

    @property
    def samples(self) -> int:
        """The rows kept in memory."""
        return 0 if self.result is None else len(self.result)

    def __iter__(self) -> Iterator[Any]:
        """``result, metadata = run(...)``: read as the pair `cosim.run.simulation.run` returned before."""
        return iter((self.result, self.metadata))

    def __getitem__(self, index: int) -> Any:
        """``run(...)[0]`` the result, ``[1]`` the metadata, as of the pair."""
        return (self.result, self.metadata)[index]
