"""Live FMU instances: one `Instance` protocol, implemented per interface kind.

`open_instance` returns the instance for an `cosim.model.fmu.FMUDescription`'s kind.
"""
from __future__ import annotations

from ...model.fmu import FMUDescription
from ...model.structure import SolverSettings
from .base import STATUS, Instance
from .fmi2 import FMI2Instance
from .fmi3 import FMI3Instance
from .me import ME3Instance, MEInstance
from .unzip import Unzipped

__all__ = ["STATUS", "FMI2Instance", "FMI3Instance", "Instance", "ME3Instance", "MEInstance", "Unzipped", "open_instance"]


def open_instance(name: str, desc: FMUDescription, unzip_dir: str,
                  solver: SolverSettings | None = None) -> Instance:
    """The live instance for ``desc.kind`` (not yet instantiated); ``solver``: how the master
    integrates a Model Exchange FMU (`cosim.plan.build.Plan.solvers`)."""
    if desc.kind == "fmi3-cs":
        return FMI3Instance(name, desc, unzip_dir)
    if desc.kind == "fmi2-me":
        return MEInstance(name, desc, unzip_dir, solver)
    if desc.kind == "fmi3-me":
        return ME3Instance(name, desc, unzip_dir, solver)
    return FMI2Instance(name, desc, unzip_dir)
