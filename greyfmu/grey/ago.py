"""Accumulated generating operations of grey theory (thesis 000_*, §3.1.1, (3.2a), (3.2b), (3.5b))."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def finite_vector(seq: Sequence[float] | np.ndarray, what: str) -> np.ndarray:
    """``seq`` as a 1-D float array; ValueError naming ``what`` and the first non-finite sample (1-based)."""
    x = np.asarray(seq, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"{what}: expected a one-dimensional sequence, got shape {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise ValueError(f"{what}: sample {bad[0] + 1} is {x[bad[0]]}, not a finite number")
    return x


def ago(seq: Sequence[float] | np.ndarray) -> np.ndarray:
    """First-time accumulated generating operation (3.2a): ``e1(k) = Σ_{i<=k} e0(i)`` — a discrete integral."""
    return np.cumsum(finite_vector(seq, "ago"))


def iago(seq: Sequence[float] | np.ndarray) -> np.ndarray:
    """Inverse AGO (3.2b): ``e0(1) = e1(1)``, ``e0(k) = e1(k) − e1(k−1)`` for k >= 2, so ``iago(ago(e)) = e``."""
    x = finite_vector(seq, "iago")
    return np.diff(x, prepend=0.0)


def background(seq1: Sequence[float] | np.ndarray) -> np.ndarray:
    """Background values (3.5b) of an AGO sequence: ``Z(k) = 0.5·(e1(k) + e1(k−1))`` for k = 2..n (n − 1 values)."""
    x = finite_vector(seq1, "background")
    return 0.5 * (x[1:] + x[:-1])
