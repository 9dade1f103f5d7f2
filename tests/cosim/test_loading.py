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


def test_instances_of_one_library_share_its_functions_while_one_holds_it(tmp_path):
    """Issue 42: a library is loaded and its FMI functions looked up once (a ctypes library and 36
    look-ups an instance were most of a 1000-FMU system's 1 ms per FMU), shared by the instances
    holding it; unloaded with the last of them (one freed twice frees once), and loaded and looked
    up again after."""
    from fmpy import extract

    from cfmus import build_c_fmu, fmi2_description
    from cosim.run.instances import loading

    body = ("static void start(S *s) {}\nstatic void calculate(S *s) { s->r[0] = s->time; }\n"
            "static int step(S *s, double t, double h) { s->time = t + h; return 0; }\n")
    fmu = build_c_fmu(tmp_path, "Clock", fmi2_description("Clock", [("y", 0, "output", None)], {},
                                                         "{7a3e0000-0000-4000-8000-000000000043}"), body)
    folder = extract(str(fmu), str(tmp_path / "x"))
    Slave = quick(FMU2Slave)

    def opened(name: str):
        slave = Slave(guid="{7a3e0000-0000-4000-8000-000000000043}", unzipDirectory=folder,
                      modelIdentifier="Clock", instanceName=name)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        return slave

    def close(slave) -> None:
        slave.terminate()
        slave.fmi2FreeInstance(slave.component)
        slave.freeLibrary()

    a, b = opened("a"), opened("b")
    assert a.dll is b.dll and a._functions["fmi2DoStep"] is b._functions["fmi2DoStep"]
    assert vars(a).keys() == vars(b).keys() and (b.instanceName, b.guid) == ("b", a.guid)
    held = [key for key in loading._shared if str(key[1]).startswith(str(folder))]
    assert held == [(Slave, a.dll._name)]
    close(a)
    a.freeLibrary()                        # a second free of a: b keeps the library
    b.doStep(0.0, 0.5)
    assert b.getReal([0]) == [0.5]        # the library still loaded for b
    close(b)
    assert not [key for key in loading._shared if str(key[1]).startswith(str(folder))]
    c = opened("c")                        # loaded afresh, looked up afresh
    c.doStep(0.0, 0.25)
    assert c.getReal([0]) == [0.25]
    close(c)
