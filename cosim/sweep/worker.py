"""What a sweep's worker process keeps across the runs it executes (issue 28: a sweep's
throughput close to its loops').

Every run of a sweep is the same scenario with other values for a few parameters, handed to
a worker as a `cosim.sweep.dispatch.Task`.  A worker keeps, for the last sweep it ran a run
of (one at a time):

- for a task that does not carry its plan (`cosim.sweep.dispatch.Task.prepared`: a local sweep
  prepares every run's plan in its own process and ships it pickled), the scenario read, its
  FMUs located and its shared parameter sets and input table read
  (`cosim.plan.prepare.load_scenario`): each run's plan is then made from it with the run's own
  parameter set (`cosim.plan.prepare.prepare_scenario`, the same checks as ``cosim run``'s), so the
  swept values may be parameters or start values of any kind: nothing about the plan is kept
  from one run to the next but what the run's values cannot change;
- its FMU instances, reset after each completed run and re-initialised by the next
  (`cosim.run.instances.reuse.InstancePool`), when the task asks (``Task.reuse``);
- the unpacked FMUs (`cosim.run.instances.Unzipped`, once per process anyway).

The key of what is kept is the sweep's identity digest (`Task.sweep_key`: the contents of the
scenario's files, of every FMU, of the shared parameter sets and input table, the grid, the
algorithm and the start values) with the paths the task names; a task of another sweep (a
Dask worker serves many) frees what was kept and starts again.  At exit the kept instances
are freed (`release`).
"""
from __future__ import annotations

import atexit
from dataclasses import dataclass

from ..run.instances.reuse import InstancePool
from ..plan.prepare import Prepared, Scenario, load_scenario, prepare_scenario


@dataclass
class Kept:
    """One sweep's scenario and instances, kept by a worker process."""
    key: tuple
    #: None for the tasks that carry their plan
    scenario: Scenario | None
    pool: InstancePool

    def close(self) -> None:
        try:
            self.pool.close()
        finally:
            if self.scenario is not None:
                self.scenario.close()


_KEPT: list[Kept] = []     # at most one: the last sweep's


def key_of(task) -> tuple:
    """What decides the scenario a task's runs share: the sweep's identity and the files it names."""
    shared = task.parameter_sets[:task.shared_sets]
    return (task.sweep_key, task.scenario, shared, task.fmu_dirs, task.input_file, task.max_unpacked)


def kept_for(task) -> Kept:
    """This process's kept scenario and instances for ``task``'s sweep (read now if another was kept)."""
    key = key_of(task)
    if _KEPT and _KEPT[0].key == key:
        return _KEPT[0]
    release()
    scenario = None if task.prepared is not None else \
        load_scenario(task.scenario, parameter_sets=task.parameter_sets[:task.shared_sets],
                      fmu_dirs=task.fmu_dirs, input_file=task.input_file)
    _KEPT.append(Kept(key, scenario, InstancePool()))
    return _KEPT[0]


def prepare_task(task, kept: Kept) -> Prepared:
    """The run of ``task`` on its sweep's kept scenario (not to be closed: the scenario is kept)."""
    return prepare_scenario(kept.scenario, parameter_sets=task.parameter_sets[task.shared_sets:],
                            start_values=task.start_values, start_time=task.start, stop_time=task.stop,
                            step_size=task.step, algorithm=task.algorithm)


def release() -> None:
    """Free what this process keeps (the instances, the scenario's extracted archive)."""
    while _KEPT:
        _KEPT.pop().close()


atexit.register(release)
