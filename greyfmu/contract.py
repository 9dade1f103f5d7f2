"""The component contract (design.md §2): one ``Protocol`` per role, followed by every exported component.

``Controller``: a sampled controller with its sample time named ``Ts`` [s]; ``step(r, y) -> u`` is
one sample (set-point r, measurement y, new output u, scalars or vectors), extra measured inputs
are keyword arguments (``GainScheduledPID.step(r, y, W=W)``); ``reset()`` returns to the state
right after construction.  The FMU slave calls ``step`` at every sample instant and holds u.

``Plant``: ``advance(t, h, u, d=0.0) -> y`` integrates [t, t + h] with the input u and the
disturbance d held from t (zero-order hold) and returns the output at t + h; ``reset()`` returns
to the initial state.  Vector plants take and return arrays (``BoilerTurbine``: u = the three
valve commands, y = (P, E, L); ``StochasticLTI``).

Shared numerics live once: output limits in ``greyfmu.control.limits``, RK4 with sub-steps in
``greyfmu.plants.integration``, GPC's cost weights and QP terms in ``greyfmu.control.gpc``.

Documented exceptions (tests/greyfmu/test_contract.py lists them and checks that each still
deviates, so the list cannot go stale):

- ``GPC``, ``OSMMGPC``, ``DigitalPI``: no ``Ts``.  Their laws are in samples on a discrete model
  (CARIMA (33), TS-ARX (28), the discretised plant (9)/(10)); the sample time belongs to the
  model's identification or design (``DigitalPIDesign.Ts``) and to the FMU's ``Ts`` parameter.
- ``SteamHeader.advance(t, h, u, v)``: the valve openings v are the header's load, a second
  required input vector (fraction open), not a disturbance with a zero default.
- ``FourTank.step(u1, u2)``: the paper's plant (41)-(42) is a difference equation in samples of
  ``Ts``; it has no continuous time to advance over.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Controller(Protocol):
    """A sampled controller: sample time ``Ts``, ``step(r, y, **measured) -> u``, ``reset()``."""

    Ts: float

    def step(self, r: Any, y: Any, /, **measured: Any) -> Any:
        """One sample with set-point r and measurement y (extra measured inputs by keyword); returns u."""
        ...

    def reset(self) -> None:
        """Return to the state right after construction."""
        ...


@runtime_checkable
class Plant(Protocol):
    """A plant integrated over the caller's step: ``advance(t, h, u, d=0.0) -> y``, ``reset()``."""

    def advance(self, t: float, h: float, u: Any, d: Any = 0.0) -> Any:
        """Integrate [t, t + h] with u and d held from t; returns the output y(t + h)."""
        ...

    def reset(self) -> None:
        """Return to the initial state."""
        ...
