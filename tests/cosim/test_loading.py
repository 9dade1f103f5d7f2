"""`cosim.run.instances.loading.quick`: fmpy's FMU classes, their FMI functions loaded from a table
made once per class, equal to what fmpy's own ``_loadFunctions`` sets on each instance."""
from __future__ import annotations

import pytest
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

from cosim.run.instances.loading import quick


class _Library:
    """A stand-in for the ctypes library: each name gives a fresh object to set attributes on."""

    def __getattr__(self, name: str):
        return type(name, (), {})()


def _functions(cls: type) -> dict:
    probe = type(cls.__name__, (cls,), {"__init__": lambda self: setattr(self, "_functions", {})})()
    probe.dll = _Library()
    probe._loadFunctions()
    return {name: (f.argnames, f.argtypes, f.restype) for name, f in probe._functions.items()}


@pytest.mark.parametrize("cls", [FMU2Slave, FMU2Model, FMU3Slave, FMU3Model])
def test_quick_loading_sets_what_fmpy_sets(cls):
    assert issubclass(quick(cls), cls) and quick(cls).__name__ == cls.__name__
    fmpy_own, ours = _functions(cls), _functions(quick(cls))
    assert len(ours) > 30 and ours == fmpy_own
