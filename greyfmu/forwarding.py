"""Hand greyfmu's warnings to a host's log: the FMU-log bridge's greyfmu half (no FMI here).

greyfmu reports fallbacks two ways: ``logging`` warnings under the ``greyfmu`` logger (a NaN
measurement held, an infeasible QP, a refused scheduling variable) and Python ``warnings`` (an
off-line design outside the paper's advice, ``HorizonWarning``; numpy's and scipy's).  Both reach
the `WarningSink` whose call raised them, every occurrence, through two routes installed once per
process and paid only when a warning fires (per call one identity comparison, `keep_routing`;
nothing entered, added or allocated):

- `Handler`, added once to greyfmu's package logger (`LOGGER`), for the records of level WARNING
  or above; the record still propagates to the host's handlers as before;
- the route, one entry ``("ignore", route, Warning, None, 0)`` at the front of ``warnings.filters``,
  whose message matcher is a `Route`: ``warnings`` calls its ``match(text)`` for every warning
  raised in the process, before any other filter; inside a sink's call it hands the text to the
  sink and answers True (the action "ignore": never shown on the host's stderr, never raised by a
  host's "error" filter, nothing stored in a ``__warningregistry__``, so the next occurrence
  comes again), elsewhere False (the host's filters decide, as without greyfmu).

Whose call: the innermost frame of the calling thread's stack that runs one of the functions
registered with `forward_from` (the slave bases register the methods a host calls and the ones
building or retuning the greyfmu objects); its ``self`` is the sink.  A frame, not a variable set
on entry: the calls pay nothing, and threads stepping instances at once each find their own.

The route must lead ``warnings.filters``, which a host may change at any time (``catch_warnings``
blocks restore a list without it, ``simplefilter`` inserts before it, ``resetwarnings`` empties
it), so the calls that run greyfmu's code (the slave bases' step, build and retune) begin with
`keep_routing`: one identity comparison, and the route put back in front when it was moved.  Several FMUs of ours in one process (each with its private copy
of this module, greyfmu.privatise), of this release or another, share one route: a copy that
finds a route at the front adopts it (``greyfmu_route``, the version of this protocol, is 1: a
route has ``register(codes)``, and a sink ``forward_warning(message)``), so no two copies take the
front from each other at every step.

Left as without greyfmu: a warning whose location (``text``, category, line) its module's
``__warningregistry__`` already holds from an occurrence outside a sink's call (the registry is
read before the filters); a host whose logging configuration disables greyfmu's loggers.
"""

from __future__ import annotations

import logging
import sys
import warnings
from collections.abc import Callable, Iterable
from types import CodeType, FrameType
from typing import Protocol

LOGGER = logging.getLogger(__name__.rpartition(".")[0])
"""greyfmu's package logger, under the name this copy of greyfmu is imported as (inside an FMU, its
private package's ``<package>.greyfmu``, greyfmu.privatise: each FMU forwards its own numerics' warnings)."""

PROTOCOL = 1
"""The version of the route's protocol (see the module docstring), shared by every copy of this module."""


class WarningSink(Protocol):
    """What receives the warnings raised in its calls: an FMU instance, which logs them."""

    def forward_warning(self, message: str) -> None:
        """Log ``message`` (the warning's text, or the record's message) as this instance's warning."""


class Route:
    """The message matcher of the route's entry in ``warnings.filters`` (see the module docstring)."""

    greyfmu_route = PROTOCOL

    def __init__(self) -> None:
        self.codes: set[CodeType] = set()
        """The code objects of the functions whose frames' ``self`` is a sink, of every copy registered."""

    def register(self, codes: Iterable[CodeType]) -> None:
        """Route the warnings raised in frames running ``codes`` too."""
        self.codes.update(codes)

    def sink(self, frame: FrameType | None) -> WarningSink | None:
        """The ``self`` of the innermost frame from ``frame`` outwards that runs a registered code, or None."""
        codes = self.codes
        while frame is not None:
            if frame.f_code in codes:
                return frame.f_locals.get("self")
            frame = frame.f_back
        return None

    def match(self, text: str) -> bool:
        """True (ignore it) after handing ``text`` to the sink whose call raised the warning; False
        outside any sink's call.  Never raises: an exception here would leave ``warnings.warn``."""
        try:
            sink = self.sink(sys._getframe(1))
            if sink is None:
                return False
            sink.forward_warning(text)
            return True
        except Exception:
            return False


_codes: set[CodeType] = set()
"""The code objects this copy registered (`forward_from`), registered again with a route it adopts."""
_entry: tuple = ("ignore", Route(), Warning, None, 0)
"""The route's entry in ``warnings.filters``: this copy's, or the one it adopted."""


def forward_from(*functions: Callable) -> None:
    """Route the warnings raised while one of ``functions`` runs to its ``self`` (a `WarningSink`)."""
    codes = {function.__code__ for function in functions}
    _codes.update(codes)
    _entry[1].register(codes)
    keep_routing()


def keep_routing() -> None:
    """Put the route back at the front of ``warnings.filters`` if the host moved it (see the module
    docstring); what a sink's call does first."""
    filters = warnings.filters
    if not filters or filters[0] is not _entry:
        _lead(filters)


def _lead(filters: list) -> None:
    """Adopt the route at the front of ``filters`` (another copy's) or put this copy's route there."""
    global _entry
    head = filters[0] if filters else None
    if isinstance(head, tuple) and len(head) == 5 and getattr(head[1], "greyfmu_route", None) == PROTOCOL:
        head[1].register(_codes)
        _entry = head
        return
    while _entry in filters:
        filters.remove(_entry)
    filters.insert(0, _entry)
    mutated = getattr(warnings, "_filters_mutated", None)
    if mutated is not None:
        mutated()  # the registries' "already warned" entries made under the filters before are void


class Handler(logging.Handler):
    """Added once to `LOGGER`: a record of level WARNING or above logged in a sink's call goes to that
    sink; outside one, to Python's last-resort handler when no other handler would take it (as
    without this handler)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)

    def emit(self, record: logging.LogRecord) -> None:
        sink = _entry[1].sink(sys._getframe(1))
        if sink is not None:
            sink.forward_warning(record.getMessage())
        elif not self._others_take(record) and logging.lastResort is not None \
                and record.levelno >= logging.lastResort.level:
            logging.lastResort.handle(record)

    def _others_take(self, record: logging.LogRecord) -> bool:
        """Whether a handler other than this one is on the record's way up (``Logger.callHandlers``)."""
        logger: logging.Logger | None = logging.getLogger(record.name)
        while logger is not None:
            if any(handler is not self for handler in logger.handlers):
                return True
            logger = logger.parent if logger.propagate else None
        return False


LOGGER.addHandler(Handler())
