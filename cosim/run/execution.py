"""The lifecycle of one run: instantiate (or take from the pool), link the step's program to the
instances, initialise, step from start to stop, close; and the metadata of how it went.

The step is compiled from the plan alone into a program of operations (`cosim.run.program`), the
only description of what the master does in a communication step; `link` (`cosim.run.link`) gives
it this run's instances and buffers, and `cosim.run.stepping` runs it from start to stop on one of
its two interpreters (`cosim.run.interpreters`), handling the FMI statuses they hand back.
`cosim.run.simulation.run` assembles a run from these, in that order.

Algorithms (recorded in the result metadata):

* ``jacobi`` (default): every FMU steps from the inputs of the last
  communication point; then outputs are read and routed.
* ``gauss-seidel``: FMUs step one after the other in dependency order, each
  seeing the outputs its upstream FMUs have just computed.

At every communication point (and during initialisation) the exchange reads
all outputs, then re-reads the outputs of direct-feedthrough FMUs after
setting their inputs, in dependency order, so a chain of feedthrough blocks
(sums, gains) settles within the instant instead of lagging one step per
block.  Without feedthrough this is plain Jacobi, as libcosim does it.  An
algebraic loop of direct feedthrough is solved by repeating that settling sweep
(`cosim.run.loops.LoopSolver`), or broken by one step of delay (``loops="delay"``).

Kernels (``kernel``, recorded in the metadata): "native" runs the program in the compiled loop
of `cosim.kernel`, which hands back to Python each operation it cannot make (a Model Exchange
doStep, an isolated component's calls, a String route, a transformation without a C form, an
input table, an algebraic loop's iteration: counted by reason in the metadata's
``python_operations``), with bit-identical results; "python" runs every operation in Python;
"auto" (default) the compiled loop when the library is built and it has an operation to make,
else Python, saying why (``kernel_reason``).
"""
from __future__ import annotations

import time as _time
import warnings
from pathlib import Path

from ..errors import ComponentLost, RunError
from ..model.fmu import FMUDescription
from ..model.grid import Grid
from ..model.structure import Plan
from ..record.observers import Recorder
from .instances import Instance, Unzipped, open_instance
from .instances.base import STATUS, fmi_failure
from .instances.isolated import Isolation
from .instances.reuse import InstancePool
from .interpreters import Choice, check_kernel, choose_interpreter
from .interrupts import StopRequest
from .link import LinkedProgram, link
from .loops import LoopSettings
from .program import StepProgram
from .stepping import Stepping

__all__ = ["Execution"]


class Execution:
    """One run of a plan on a grid: `instantiate`, `link` the compiled step to the instances,
    `initialize`, `run` into a recorder, `close`; `metadata` says how it ran.  ``kernel`` and
    ``threads`` (checked here, `cosim.run.interpreters.check_kernel`): which interpreter runs the
    step, and on how many threads; ``isolation``: each component in a process of its own
    (`cosim.run.instances.isolated`); ``pool``: instances kept across runs
    (`cosim.run.instances.reuse`)."""

    def __init__(self, plan: Plan, grid: Grid, algorithm: str = "jacobi", fmu_log: str = "errors",
                 loop_settings: LoopSettings | None = None, isolation: Isolation | None = None,
                 kernel: str = "auto", threads: int = 1, pool: InstancePool | None = None):
        check_kernel(algorithm, kernel, threads)
        self.plan = plan
        self.grid = grid
        self.algorithm = algorithm
        self.fmu_log = fmu_log
        self.loop_settings = loop_settings or LoopSettings()
        #: each component in a process of its own (``--isolate``), or all in this one (None)
        self.isolation = isolation
        self.instances: dict[str, Instance] = {}
        #: instances kept across runs (`cosim.run.instances.reuse`): taken from it, given back at `close`
        self.pool = pool if isolation is None else None
        #: the components whose instance came from ``pool`` (reset after an earlier run)
        self.reused: list[str] = []
        self._unzipped = Unzipped()
        self.loop_seconds = 0.0
        self.status = "not started"
        self.message = ""
        self.kernel_requested = kernel
        self.threads = threads
        if plan.algebraic_loops and plan.loop_mode == "delay":
            warnings.warn("algebraic loop broken by one step of delay (--loops delay): "
                          + "; ".join(loop.describe() for loop in plan.algebraic_loops), RuntimeWarning, stacklevel=2)
        #: the step linked to the instances (`link`), and the interpreter chosen to run it
        self.linked: LinkedProgram | None = None
        self.choice: Choice | None = None
        self._stepping: Stepping | None = None

    @property
    def last_time(self) -> float:
        """The last communication point recorded (the start time before the first step)."""
        return self._stepping.last_time if self._stepping is not None else self.grid.start

    # ----------------------------------------------------------------- set-up

    def instantiate(self) -> None:
        """Instantiate every component (or take it from the pool); each FMU file's folder is looked
        up once."""
        folders: dict[Path, str] = {}
        for name in self.plan.components:
            desc = self.plan.fmus[name]
            kept = self.pool.take(name, desc, self.fmu_log) if self.pool is not None else None
            if kept is not None:
                self.instances[name] = kept
                self.reused.append(name)
                continue
            opened = open_instance if self.isolation is None else self.isolation.open
            if desc.path not in folders:
                folders[desc.path] = self._unzipped(desc.path)
            inst = opened(name, desc, folders[desc.path], self.plan.solvers.get(name))
            self.instances[name] = inst
            inst.instantiate(self.fmu_log)

    def link(self, program: StepProgram) -> LinkedProgram:
        """The compiled step on this run's instances (`cosim.run.link.link`), and its interpreter
        (`cosim.run.interpreters.choose_interpreter`)."""
        self.linked = link(program, self.instances, self.grid, self.loop_settings, self.threads)
        self.choice = choose_interpreter(self.linked, self.grid, self.kernel_requested, self.threads)
        self._stepping = Stepping(self.linked, self.grid, self.choice.interpreter)
        return self.linked

    def initialize(self) -> None:
        """Set up the experiment, set the start values, enter initialisation mode, read the
        inputs' start values, exchange, leave initialisation mode and exchange again."""
        t0, stop = self.grid.start, self.grid.stop
        for name, inst in self.instances.items():
            self._guard(name, t0, "setting up the experiment", lambda: inst.setup_experiment(t0, stop))
        for sv in self.plan.start_values:
            inst = self.instances[sv.component]
            self._guard(sv.component, t0, f"setting {sv.variable.name} = {sv.value} (from {sv.origin})",
                        lambda: inst.set_start(sv.variable, sv.value))
        for name, inst in self.instances.items():
            self._guard(name, t0, "entering initialization mode", inst.enter_initialization_mode)
        self._read_input_starts(t0)
        self.choice.python.exchange(t0)
        for name, inst in self.instances.items():
            self._guard(name, t0, "exiting initialization mode", inst.exit_initialization_mode)
        self.choice.python.exchange(t0)

    def _read_input_starts(self, t0: float) -> None:
        """Unconnected inputs keep the FMU's (or the binding's) start value: every input is read
        into the input buffers before the first exchange."""
        for comp in self.plan.components:
            inst = self.instances[comp]
            for ty in self.linked.buffers:
                start, n, vr = ty.in_slices[comp]
                if n:
                    get = ty.get_call(inst.get[ty.type_name], ty.Ubuf, start, n)
                    status = get(inst.component, vr, n, ty.pointer(ty.Ubuf, start))
                    if status > 1:
                        raise fmi_failure(inst, "Get (inputs)", status, t0)

    def _guard(self, comp: str, t: float, what: str, call) -> None:
        """A set-up ``call`` of ``comp``: its failure is a `RunError` saying ``what`` failed at ``t``."""
        try:
            call()
        except ComponentLost:  # names the component, the call and t already
            raise
        except Exception as e:
            inst = self.instances[comp]
            status = getattr(e, "status", None)
            if status is not None and status >= 3:
                inst.failed = STATUS.get(status, "Fatal")
            raise RunError(f"{what} failed at t = {t:g}: {e}.{inst.last_messages()}", time=t, component=comp,
                           element=f"component '{comp}' ({inst.desc.path.name})") from None

    # ----------------------------------------------------------------- stepping

    def run(self, recorder: Recorder, progress=None, stop: StopRequest | None = None) -> None:
        """Step from start to stop; ``status`` ends as completed, terminated (an FMU ended the run
        after a valid step, recorded), discarded (an FMU could not complete a step), or (when
        ``stop`` is set by a signal, checked at every communication point) interrupted or
        timeout; a failure raises (`cosim.errors.RunError`)."""
        recorder.record(self.grid.start)
        self.status = "running"
        started = _time.perf_counter()
        try:
            ending = self._stepping.run(recorder, progress, stop)
        finally:
            self.loop_seconds = _time.perf_counter() - started
        self.status, self.message = ending.status, ending.message

    def close(self) -> None:
        """End the compiled loop's threads, then free the instances (or give them back to the pool)."""
        if self.choice is not None:
            self.choice.interpreter.close()
        for inst in self.instances.values():
            if self.pool is not None:
                self.pool.give(inst, self.status == "completed", self.fmu_log)
            else:
                inst.free()
        self.instances.clear()

    def _component_metadata(self, name: str, d: FMUDescription) -> dict:
        meta = {"fmu": str(d.path), "guid": d.guid, "generation_tool": d.generation_tool, "interface": d.kind}
        if d.kind in ("fmi2-me", "fmi3-me"):  # integrated by the master (cosim.run.instances.me)
            meta["solver"] = self.plan.solvers[name].as_dict()
        return meta

    def _loop_metadata(self) -> dict | None:
        if self.linked is not None and self.linked.loop_solver is not None:
            return self.linked.loop_solver.metadata()
        if self.plan.algebraic_loops:
            return {"mode": "delay", "loops": [loop.describe() for loop in self.plan.algebraic_loops]}
        return None

    def metadata(self) -> dict:
        """How the run went and ran: algorithm, interpreter (``kernel``, and ``python_operations``
        or ``kernel_reason``), threads, loops, grid, status, components, reuse and parameters."""
        linked, choice = self.linked, self.choice
        name, reason = (choice.name, choice.reason) if choice is not None else ("python", "")
        in_python = linked.python_operations() if linked is not None and name == "native" else {}
        kernel = {"kernel": name} | ({"kernel_reason": reason} if reason else {}) \
            | ({"python_operations": in_python} if in_python else {}) \
            | ({"threads": self.threads, "parallel_components": list(linked.parallel_components),
                "serial_components": dict(linked.serial)} if self.threads > 1 and linked is not None else {})
        return {
            "algorithm": self.algorithm, **kernel,
            "gauss_seidel_order": list(self.plan.gauss_seidel_order) if self.algorithm == "gauss-seidel" else None,
            "feedthrough_sequence": list(self.plan.feedthrough_sequence),
            "algebraic_loops": self._loop_metadata(),
            "start_time": self.grid.start, "stop_time": self.grid.stop, "step_size": self.grid.step,
            "status": self.status, "last_time": self.last_time, "message": self.message,
            "error": None,  # the `cosim.errors.Errc` of a run that fails: `cosim.run.simulation` sets it
            "steps": self.grid.steps, "loop_seconds": self.loop_seconds,
            "components": {name: self._component_metadata(name, d) for name, d in self.plan.fmus.items()},
            **({"reused_instances": self.reused,
                "reset_refused": {Path(fmu).name: why for fmu, why in self.pool.refused.items()}}
               if self.pool is not None else {}),
            "parameters": {f"{sv.component}.{sv.variable.name}": sv.value for sv in self.plan.start_values},
            "finished_at": _time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
