"""Controllers as plain classes: one ``step`` per sample, ``reset()`` to start over."""

from greyfmu.control.pid import PID, IntegralMode, integral_step

__all__ = ["PID", "IntegralMode", "integral_step"]
