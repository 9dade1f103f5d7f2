"""Error-prediction-based grey predictive PI (thesis 000_*, §3.2, Fig. 3.14, (3.29a)-(3.29d))."""

from __future__ import annotations

import math

from greyfmu.control.pid import PID, IntegralMode, PIForm
from greyfmu.grey.predictor import GreyPredictor, PredictorMode, Threshold


class GrayPredictivePI:
    """PI acting on the grey prediction of the control error, Fig. 3.14.

    Each sample k (sample time Ts):

    - ``e(k) = r − y(k)`` (3.29a); the `GreyPredictor` fits GM(1,1) to the biased errors
      ``e + B`` (3.29b) of a window of n samples spaced m samples apart (LDISPI, §3.1.6) and
      returns ``ê = ê_b − B``, ``ph`` seconds ahead (3.29c)/(3.29d) when a > a_min (``threshold``
      SIGNED, §4.2 as printed; MAGNITUDE: |a| > a_min), the estimate of the current error
      otherwise;
    - the PI is the `PID` with Td = 0 fed with ê: ``u(k) = Kc·ê(k) + I(k)``, its integral
      law (2.10)-(2.12), limits, rate limit, anti-windup (``anti_windup=False``: the
      thesis's PI) and form (``PIForm.PARALLEL``: §4.2's printed Kc·e + (1/Ti)∫e) unchanged.

    With a constant error the predictor gives a → 0 and ê → e (Propositions 3.4/3.5), so
    the loop has the steady state of the plain PI: no offset (Theorem 3.5).  Until the
    window is full (the first (n − 1)·m samples) ê = e and the controller is the plain PI.
    """

    def __init__(
        self,
        Kc: float,
        Ti: float,
        Ts: float = 1.0,
        *,
        n: int = 4,
        m: int = 5,
        ph: float = 25.0,
        B: float = 50.0,
        a_min: float = 0.035,
        u_min: float = -math.inf,
        u_max: float = math.inf,
        du_max: float = 0.0,
        integral_mode: IntegralMode | int = IntegralMode.METHOD3,
        u0: float = 0.0,
        anti_windup: bool = True,
        threshold: Threshold | int = Threshold.SIGNED,
        form: PIForm | int = PIForm.ISA,
    ) -> None:
        self.pi = PID(Kc, Ti, 0.0, Ts, u_min=u_min, u_max=u_max, du_max=du_max, integral_mode=integral_mode, u0=u0,
                      anti_windup=anti_windup, form=form)
        if not (math.isfinite(ph) and ph >= 0.0):
            raise ValueError(f"GrayPredictivePI: prediction horizon ph must be a finite number >= 0 s, got {ph}")
        self.Ts = Ts
        self.ph = ph
        self.predictor = GreyPredictor(n=n, m=m, horizon=ph / Ts, bias=B, a_min=a_min, threshold=threshold)
        self.e = 0.0
        self.e_hat = 0.0
        """Predicted (or estimated) error the PI acted on at the last sample."""

    @property
    def u(self) -> float:
        """Controller output of the last sample (u0 before the first)."""
        return self.pi.u

    @property
    def mode(self) -> PredictorMode:
        return self.predictor.mode

    def reset(self) -> None:
        """Return to the state right after construction (PI at u0, empty prediction window)."""
        self.pi.reset()
        self.predictor.reset()
        self.e = 0.0
        self.e_hat = 0.0

    def step(self, r: float, y: float) -> float:
        """One sample: set-point r, measurement y; returns u(k)."""
        self.e = r - y
        self.e_hat = self.predictor.update(self.e)
        return self.pi.step(self.e_hat, 0.0)
