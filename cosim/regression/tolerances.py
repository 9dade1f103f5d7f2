"""Per-signal tolerances chosen by glob, and the width of the band they give at each point.

A `Tolerance` is the half-height of the tolerance rectangle LBNL's funnel builds around each
reference point (github:lbl-srg/funnel, src/tubeSize.c ``set_tube_size``): an absolute floor
``atol`` for signals near zero and a band ``rtol``·|reference| elsewhere, whichever is wider
(the funnel's ``atoly`` and ``ltoly``), and its half-width ``time`` in seconds (the funnel's
``atolx``): an event may move by up to ``time`` and still pass (`cosim.regression.tube`).
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import SetupError, did_you_mean
from ..record.results import matches


@dataclass(frozen=True)
class Tolerance:
    """|run − reference| <= max(atol, rtol·|reference|), the reference taken anywhere within ±time s."""
    rtol: float = 1e-6
    atol: float = 1e-9
    time: float = 0.0

    def half_height(self, reference: np.ndarray) -> np.ndarray:
        """The band's half-height at each reference value: max(atol, rtol·|reference|)."""
        return np.maximum(self.atol, self.rtol * np.abs(reference))

    def __str__(self) -> str:
        return f"rtol {self.rtol:g}, atol {self.atol:g}" + (f", time ±{self.time:g} s" if self.time else "")


#: what a caller may give per signal: a Tolerance, (rtol, atol), (rtol, atol, time), or a mapping
#: with any of "rtol", "atol", "time" (a missing one takes the default's)
ToleranceSpec = Tolerance | tuple | Mapping[str, float]
FIELDS = ("rtol", "atol", "time")


def as_tolerance(spec: ToleranceSpec, default: Tolerance, key: str = "") -> Tolerance:
    """A `Tolerance` from any `ToleranceSpec`; unknown fields, negative or non-finite values are refused."""
    if isinstance(spec, Tolerance):
        tol = spec
    elif isinstance(spec, Mapping):
        unknown = set(spec) - set(FIELDS)
        if unknown:
            raise SetupError(f"unknown tolerance field(s) {', '.join(sorted(unknown))}; use {', '.join(FIELDS)}.",
                             variable=key or None)
        tol = Tolerance(*(float(spec.get(f, getattr(default, f))) for f in FIELDS))
    elif isinstance(spec, (tuple, list)) and len(spec) in (2, 3):
        tol = Tolerance(*(float(v) for v in spec))
    else:
        raise SetupError(f"a tolerance is (rtol, atol), (rtol, atol, time) or a mapping of {', '.join(FIELDS)}, "
                         f"not {spec!r}.", variable=key or None)
    if not all(np.isfinite(getattr(tol, f)) and getattr(tol, f) >= 0 for f in FIELDS):
        raise SetupError(f"tolerances must be finite and >= 0 ({tol}).", variable=key or None)
    return tol


def parse_tolerance(text: str) -> tuple[str, Tolerance]:
    """``"GLOB=RTOL,ATOL[,TIME]"`` (``cosim compare --tolerance``) as (glob, Tolerance)."""
    key, _, values = text.partition("=")
    parts = values.split(",")
    try:
        if not key.strip() or len(parts) not in (2, 3):
            raise ValueError
        spec = tuple(float(p) for p in parts)
    except ValueError:
        raise SetupError(f"'{text}' is not GLOB=RTOL,ATOL[,TIME] (e.g. 'plant.y=1e-6,1e-9' or "
                         "'valve.*=1e-3,1e-6,0.1').", element="--tolerance") from None
    return key.strip(), as_tolerance(spec, Tolerance(), key.strip())


def _literal_length(pattern: str) -> int:
    """How much of a glob is fixed text: the measure of how specific a tolerance key is (brackets
    are literal, `cosim.record.results.matches`)."""
    return len(re.sub(r"[*?]", "", pattern))


def tolerance_for(signal: str, tolerances: Mapping[str, ToleranceSpec], default: Tolerance) -> Tolerance:
    """The tolerance of ``signal``: the most specific glob key that matches it wins (an exact
    name beats any pattern; among patterns, the one with the most fixed characters, then the
    first given), else ``default``."""
    if signal in tolerances:
        return as_tolerance(tolerances[signal], default, signal)
    keys = [k for k in tolerances if matches(signal, k)]
    if not keys:
        return default
    best = max(keys, key=_literal_length)   # max keeps the first of equals
    return as_tolerance(tolerances[best], default, best)


def check_tolerance_keys(tolerances: Mapping[str, ToleranceSpec], names: Sequence[str]) -> None:
    """Refuse a tolerance key that matches none of ``names`` (a misspelt key must not go unnoticed)."""
    for key in tolerances:
        if not any(key == n or matches(n, key) for n in names):
            raise SetupError("this tolerance key matches no compared signal.", variable=key,
                             hint=did_you_mean(key, names))
