"""Instances kept across runs: reset after a run, handed to the next run of the same component.

A sweep worker runs the same system many times with other parameter values; instantiating
each FMU again every run (loading its library, ``fmi2Instantiate``: for a pythonfmu FMU a new
Python object of its slave) is most of a short run's fixed cost.  FMI 2.0 §2.1.6 defines
``fmi2Reset``: "the FMU goes into the same state as if fmi2Instantiate would have been called";
FMI 3.0 §2.3.1 ``fmi3Reset`` the same.  `InstancePool` keeps each instance a run ended with,
after ``terminate`` (as a fresh run ends it) and the reset, and gives it to the next run of the
same component of the same FMU, which then sets up the experiment, its start values and
initialises as on a fresh instance (`cosim.run.execution.Execution.initialize`).

An instance is not kept, but freed as before, when the run did not end "completed" (a failed,
discarded, terminated or interrupted run leaves the FMU in a state not worth trusting), when its
FMU's interface is not FMI 2.0 or 3.0 Co-Simulation (a Model Exchange instance's integrator
state lives in the master, `cosim.run.instances.me`), or when the reset returned an error or raised:
that FMU is then never reset again in this process (`refused`), and every later run instantiates
it afresh.

What a reset cannot cover is state outside the instance: a library's global variables, a
pythonfmu slave's module or class attributes.  Fresh instances in one process share those
too (a library is loaded once per process), so a sweep of fresh instances in a worker depends
on them the same way; the sweep's equality tests (tests/scenarios/sweep/test_reuse.py) compare
reused instances with `cosim run`s in fresh processes on every scenario family of ssp/.
"""
from __future__ import annotations

from ...model.fmu import FMUDescription
from .base import Instance
from .fmi2 import FMI2Instance
from .fmi3 import FMI3Instance

#: the instance classes whose reset returns them to the state of a fresh instantiation
RESETTABLE = (FMI2Instance, FMI3Instance)


class InstancePool:
    """The reset instances of a process, by component name and FMU, for the next run."""

    def __init__(self) -> None:
        self._kept: dict[tuple[str, str, str, str], Instance] = {}
        #: FMU files (path) whose reset failed, with why: instantiated afresh from then on
        self.refused: dict[str, str] = {}
        #: how many instances were handed out again
        self.reused = 0

    @staticmethod
    def _key(name: str, desc: FMUDescription, fmu_log: str) -> tuple[str, str, str, str]:
        return name, str(desc.path), desc.kind, fmu_log    # fmu_log: instantiated with logging on or off

    def take(self, name: str, desc: FMUDescription, fmu_log: str) -> Instance | None:
        """The kept instance of component ``name`` of this FMU instantiated for ``fmu_log``, or None."""
        inst = self._kept.pop(self._key(name, desc, fmu_log), None)
        if inst is not None:
            inst.reuse(fmu_log)
            self.reused += 1
        return inst

    def give(self, inst: Instance, completed: bool, fmu_log: str) -> None:
        """After a run: keep ``inst`` reset when it can be (see the module docstring), else free it."""
        path = str(inst.desc.path)
        if not completed or type(inst) not in RESETTABLE or inst.failed is not None or path in self.refused \
                or inst.component is None:
            inst.free()
            return
        try:
            inst.slave.terminate()
            inst.slave.reset()
        except Exception as e:  # noqa: BLE001 -- a reset refused: this FMU is instantiated afresh from now on
            self.refused[path] = f"{inst.api}Reset failed: {e}"
            inst.free()
            return
        self._kept[self._key(inst.name, inst.desc, fmu_log)] = inst

    def close(self) -> None:
        """Free every kept instance."""
        while self._kept:
            _, inst = self._kept.popitem()
            inst.free()
