"""Errors a user can cause, each naming the file, the element and the variable.

`SetupError` is raised before anything is instantiated (bad SSP, bad FMU, bad
options); the CLI turns it into one paragraph and exit status 2.  `RunError` is
raised while stepping; the results written up to the last good step are kept.
`OutputError` is a result file that could not be written during the run (exit 1).

Every error carries an `Errc` code, on the model of libcosim's ``cosim::errc``
(libcosim/include/cosim/error.hpp): the CLI's exit status and wording, the sweep table's
``error`` column and the pytest plugin's report branch on the code, never on the class or
the message.
"""
from __future__ import annotations

import difflib
import enum
from collections.abc import Iterable
from typing import Any


class Errc(str, enum.Enum):
    """What kind of failure an error is (libcosim's errc: invalid_system_structure,
    model_error, ... ); the value is what the sweep table and JSON write."""

    invalid_system = "invalid_system"
    """The SSP, an FMU, a parameter set, an input table or an option cannot be run as given."""
    model_error = "model_error"
    """An FMU returned an error or fatal status, or a non-finite value, while the system ran."""
    component_crashed = "component_crashed"
    """An isolated component's process died during an FMU call (``--isolate``)."""
    component_timeout = "component_timeout"
    """An isolated component did not answer an FMU call within the call timeout."""
    output_error = "output_error"
    """A result file could not be written during the run (a full disk)."""
    out_of_memory = "out_of_memory"
    """The process ran out of memory during the run."""
    run_process_lost = "run_process_lost"
    """The process running the system died or was stopped (a crash inside an FMU, ``--timeout``,
    a supervisor that died): the rows journaled before it are recovered (`cosim.record.journal`)."""
    worker_lost = "worker_lost"
    """A sweep's worker process died during the run (BrokenProcessPool, Dask's KilledWorker)."""
    unexpected = "unexpected"
    """An exception that is not cosim's (a bug, or a failure of the sweep's machinery); the
    message names its type."""

    @property
    def run_failed(self) -> bool:
        """The run started and failed (results up to the last good step kept), as opposed to
        input that could not be run at all."""
        return self is not Errc.invalid_system

    @property
    def exit_status(self) -> int:
        """The CLI's exit status: 1 for a run that failed, 2 for input that cannot be run."""
        return 1 if self.run_failed else 2


#: Longest message shown (characters); the middle of a longer one is cut.
MAX_MESSAGE = 4000


class CosimError(Exception):
    """Base class: a message built from where the problem is and what was expected."""

    code: Errc = Errc.invalid_system
    #: a failed run's `cosim.run.outcome.RunOutcome` (what it recorded up to the failure), set by
    #: `cosim.run.simulation.run` as the error leaves it; None for an error before any run
    run_outcome: Any = None

    def __init__(self, message: str, *, file: str | None = None, element: str | None = None,
                 variable: str | None = None, hint: str | None = None):
        self.file = file
        self.element = element
        self.variable = variable
        self.hint = hint
        self.detail = message
        super().__init__(self._compose())

    @property
    def result(self) -> Any:
        """The samples a failed run recorded up to the failure (``run_outcome.result``), or None."""
        return self.run_outcome.result if self.run_outcome is not None else None

    def extended(self, text: str) -> CosimError:
        """A copy of this error with ``text`` appended to its detail (what went wrong after it)."""
        error = type(self).__new__(type(self))  # not copy.copy: it would call __init__ with the text alone
        error.__dict__.update(self.__dict__)
        error.detail = f"{self.detail}{text}"
        error.args = (error._compose(),)
        return error

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

    code = Errc.model_error

    def __init__(self, message: str, *, time: float, component: str, status: int | None = None,
                 **kwargs):
        self.time = time
        self.component = component
        self.status = status
        super().__init__(message, **kwargs)


class ComponentLost(RunError):
    """A component's own process (``--isolate``, `cosim.run.instances.isolated`) died during an FMU
    call (``outcome`` "crashed") or did not answer within the call timeout ("timeout"): the
    run's status is the outcome."""

    def __init__(self, message: str, *, outcome: str, **kwargs):
        self.outcome = outcome
        self.code = Errc.component_crashed if outcome == "crashed" else Errc.component_timeout
        super().__init__(message, **kwargs)


class OutputError(CosimError):
    """A result file could not be written during the run (a full disk): the run ends, the rows
    written before stay readable."""

    code = Errc.output_error


class OutOfMemory(OutputError):
    """The process ran out of memory during the run (its address space, ``ulimit -v``, or the
    machine's): the run ends, the rows written before stay readable in the result file."""

    code = Errc.out_of_memory


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """A hint naming the closest valid names, or None when nothing is close."""
    close = difflib.get_close_matches(name, list(candidates), n=3, cutoff=0.5)
    if not close:
        return None
    return "Did you mean " + " or ".join(f"'{c}'" for c in close) + "?"


class CosimWarning(RuntimeWarning):
    """A warning of the master's about the system it runs (`cosim.plan.loopcheck.LoopWarning`: a loop
    changed silently); ``cosim --strict`` turns every one into an error (exit 2), so a warning that
    should stop a run derives from this class."""
