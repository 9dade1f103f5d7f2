"""cosim: a fixed-step co-simulation master for SSP 1.0 systems of FMI 2.0 Co-Simulation FMUs.

    >>> import cosim
    >>> result = cosim.simulate("ssp/pid_fopdt", stop_time=100, step_size=0.1)
    >>> result["plant.y"][-1]
    >>> cosim.simulate_fmu("Drive.fmu", input_file="Drive_in.csv", start_values={"gain": 3})["Drive.y"]

The master runs any FMU (it never imports the packages that built them).
"""
from .errors import CosimError, RunError, SetupError

__all__ = ["simulate", "simulate_fmu", "prepare", "CosimError", "SetupError", "RunError"]


def __getattr__(name: str):
    """`simulate` and `prepare` are imported on first use (PEP 562), so that a submodule that
    needs no FMU machinery stays cheap to import: the pytest plugin `cosim.pytest_plugin` is
    loaded into every pytest session of anyone who installs the package."""
    if name in ("simulate", "simulate_fmu"):
        from .run import simulation
        return getattr(simulation, name)
    if name == "prepare":
        from .plan.prepare import prepare
        return prepare
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")
