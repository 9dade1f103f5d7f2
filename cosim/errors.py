"""Errors a user can cause, each naming the file, the element and the variable.

`SetupError` is raised before anything is instantiated (bad SSP, bad FMU, bad
options); the CLI turns it into one paragraph and exit status 2.  `RunError` is
raised while stepping; the results written up to the last good step are kept.
`OutputError` is a result file that could not be written during the run (exit 1).
"""
from __future__ import annotations

import difflib
from collections.abc import Iterable


#: Longest message shown (characters); the middle of a longer one is cut.
MAX_MESSAGE = 4000


class CosimError(Exception):
    """Base class: a message built from where the problem is and what was expected."""

    def __init__(self, message: str, *, file: str | None = None, element: str | None = None,
                 variable: str | None = None, hint: str | None = None):
        self.file = file
        self.element = element
        self.variable = variable
        self.hint = hint
        self.detail = message
        super().__init__(self._compose())

    def _compose(self) -> str:
        where = []
        if self.file:
            where.append(str(self.file))
        if self.element:
            where.append(self.element)
        if self.variable:
            where.append(f"variable '{self.variable}'")
        text = (": ".join([", ".join(where), self.detail]) if where else self.detail)
        if self.hint:
            text += f" {self.hint}"
        if len(text) > MAX_MESSAGE:  # a malformed document can carry megabyte-long names and values
            cut = len(text) - MAX_MESSAGE
            text = f"{text[:MAX_MESSAGE // 2]} … ({cut} characters cut) … {text[-MAX_MESSAGE // 2:]}"
        return text


class SetupError(CosimError):
    """The system cannot be run as described; nothing has been instantiated yet."""


class RunError(CosimError):
    """An FMU failed while the system was running."""

    def __init__(self, message: str, *, time: float, component: str, status: int | None = None,
                 **kwargs):
        self.time = time
        self.component = component
        self.status = status
        super().__init__(message, **kwargs)


class ComponentLost(RunError):
    """A component's own process (``--isolate``, `cosim.instances.isolated`) died during an FMU
    call (``outcome`` "crashed") or did not answer within the call timeout ("timeout"): the
    run's status is the outcome."""

    def __init__(self, message: str, *, outcome: str, **kwargs):
        self.outcome = outcome
        super().__init__(message, **kwargs)


class OutputError(CosimError):
    """A result file could not be written during the run (a full disk): the run ends, the rows
    written before stay readable."""


class OutOfMemory(OutputError):
    """The process ran out of memory during the run (its address space, ``ulimit -v``, or the
    machine's): the run ends, the rows written before stay readable in the result file."""


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """A hint naming the closest valid names, or None when nothing is close."""
    close = difflib.get_close_matches(name, list(candidates), n=3, cutoff=0.5)
    if not close:
        return None
    return "Did you mean " + " or ".join(f"'{c}'" for c in close) + "?"
