"""cosim: a fixed-step co-simulation master for SSP 1.0 systems of FMI 2.0 Co-Simulation FMUs.

    >>> import cosim
    >>> result = cosim.simulate("ssp/pid_fopdt", stop_time=100, step_size=0.1)
    >>> result["plant.y"][-1]

The master runs any FMU (it never imports the packages that built them).
"""
from .errors import CosimError, RunError, SetupError
from .simulation import prepare, simulate

__all__ = ["simulate", "prepare", "CosimError", "SetupError", "RunError"]
