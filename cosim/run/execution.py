"""Run a validated plan: the lifecycle of one run -- instantiate, compile the step, initialise,
step from start to stop, close.

The step is compiled once into a program of operations (`cosim.run.program`), the only description
of what the master does in a communication step; `cosim.run.stepping` runs it from start to stop on
one of its two interpreters (`cosim.run.interpreters`), handling the FMI statuses they hand back.

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
doStep, an isolated component's calls, a String route, a mapping or input table, an algebraic
loop's iteration: counted by reason in the metadata's ``python_operations``), with bit-identical
results; "python" runs every operation in Python; "auto" (default) the compiled loop when the
library is built and it has an operation to make, else Python, saying why (``kernel_reason``).
"""
from __future__ import annotations

import time as _time
import warnings
from pathlib import Path

import numpy as np

from .. import kernel as native
from ..model.fmu import FMUDescription
from ..errors import ComponentLost, RunError, SetupError
from .exchange import TypedBuffers, exchange_buffers
from ..model.grid import Grid
from .instances import Instance, Unzipped, open_instance
from .instances.base import STATUS, fmi_failure
from .instances.isolated import Isolation
from .instances.reuse import InstancePool
from .interpreters import Interpreter, NativeInterpreter, PythonInterpreter
from .interrupts import StopRequest
from .loops import LoopSettings, LoopSolver, Watched
from ..record.observers import Recorder
from .program import Program, compile_step
from .stepping import Stepping
from ..model.structure import Plan

__all__ = ["ALGORITHMS", "KERNELS", "Execution", "Grid"]

ALGORITHMS = ("jacobi", "gauss-seidel")
KERNELS = ("auto", "native", "python")

_NOTICES: set[str] = set()


def _notice_once(reason: str) -> None:
    """Warn once per process that the Python loop runs for ``reason`` (the library is missing)."""
    if reason not in _NOTICES:
        _NOTICES.add(reason)
        warnings.warn(f"{reason}; running the Python stepping loop (same results, slower).", RuntimeWarning,
                      stacklevel=3)


class Execution:
    """One run of a plan on a grid with an algorithm, feeding a recorder: `instantiate` (and
    compile the step), `initialize`, `run`, `close`; `metadata` says how it ran."""

    def __init__(self, plan: Plan, grid: Grid, algorithm: str = "jacobi", fmu_log: str = "errors",
                 loop_settings: LoopSettings | None = None, isolation: Isolation | None = None,
                 kernel: str = "auto", threads: int = 1, pool: InstancePool | None = None):
        if algorithm not in ALGORITHMS:
            raise SetupError(f"unknown algorithm '{algorithm}'; choose one of {', '.join(ALGORITHMS)}.",
                             element="algorithm")
        if kernel not in KERNELS:
            raise SetupError(f"unknown kernel '{kernel}'; choose one of {', '.join(KERNELS)}.", element="--kernel")
        if not (isinstance(threads, int) and threads >= 1):
            raise SetupError(f"the number of threads must be a whole number of at least 1; got {threads!r}.",
                             element="--threads")
        if threads > 1 and (algorithm != "jacobi" or kernel == "python"):
            raise SetupError(f"--threads {threads} steps components in parallel within a Jacobi step of the "
                             f"compiled kernel; this run is {algorithm} with the {kernel} kernel.",
                             element="--threads", hint="Run with --threads 1, or Jacobi and --kernel auto.")
        if (kernel == "native" or threads > 1) and native.library()[0] is None:
            raise SetupError(f"the compiled kernel cannot run this system: {native.library()[1]}.",
                             element="--kernel",
                             hint="Run with --kernel auto (which then runs the Python loop) or --kernel python.")
        self.plan = plan
        self.grid = grid
        self.algorithm = algorithm
        self.fmu_log = fmu_log
        #: each component in a process of its own (``--isolate``), or all in this one (None)
        self.isolation = isolation
        self.order = list(plan.components)
        self.buffers: list[TypedBuffers] = exchange_buffers(plan, self.order)
        #: the input table's values into the input buffers at a time (`cosim.plan.inputs.InputFeed`)
        self._feed = plan.input_table.feed(self.buffers, grid) if plan.input_table is not None else None
        self.loop_solver = self._loop_solver(loop_settings or LoopSettings()) \
            if plan.algebraic_loops and plan.loop_mode == "iterate" else None
        if plan.algebraic_loops and plan.loop_mode == "delay":
            warnings.warn("algebraic loop broken by one step of delay (--loops delay): "
                          + "; ".join(loop.describe() for loop in plan.algebraic_loops), RuntimeWarning, stacklevel=2)
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
        #: the interpreter that runs ("native" or "python"), decided when the step is compiled, and
        #: under "auto" why the Python one runs
        self.kernel, self.kernel_reason = "python", ""
        #: the compiled step (`instantiate`), and what runs it
        self.program: Program | None = None
        self._python: PythonInterpreter | None = None
        self._interpreter: Interpreter | None = None
        self._stepping: Stepping | None = None

    @property
    def last_time(self) -> float:
        """The last communication point recorded (the start time before the first step)."""
        return self._stepping.last_time if self._stepping is not None else self.grid.start

    def _loop_solver(self, settings: LoopSettings) -> LoopSolver:
        """`cosim.run.loops.LoopSolver` over the exchange's output buffers: the loop outputs of each type."""
        loop_outputs = {f"{c}.{v}": (c, v) for loop in self.plan.algebraic_loops for c, v in loop.outputs}
        watched = []
        for ty in self.buffers:
            if not ty.strings:
                positions = [i for i, n in enumerate(ty.out_names) if n in loop_outputs]
                watched.append(Watched(ty.Y, np.array(positions, dtype=np.intp), ty.type_name == "Real",
                                       [loop_outputs[ty.out_names[i]] for i in positions]))
        return LoopSolver(self.plan.algebraic_loops, watched, settings, self.plan.feedthrough_sequence)

    # ----------------------------------------------------------------- set-up

    def instantiate(self) -> None:
        """Instantiate every component (or take it from the pool), then compile the step and
        choose its interpreter."""
        for name in self.order:
            desc = self.plan.fmus[name]
            kept = self.pool.take(name, desc, self.fmu_log) if self.pool is not None else None
            if kept is not None:
                self.instances[name] = kept
                self.reused.append(name)
                continue
            opened = open_instance if self.isolation is None else self.isolation.open
            inst = opened(name, desc, self._unzipped(desc.path), self.plan.solvers.get(name))
            self.instances[name] = inst
            inst.instantiate(self.fmu_log)
        self.program = compile_step(self.plan, self.buffers, self.instances, self.algorithm, self.loop_solver,
                                    self._feed, self.threads)
        self._python = PythonInterpreter(self.program, self.grid)
        self._interpreter = self._choose_interpreter()
        self._stepping = Stepping(self.program, self.grid, self._interpreter)

    def _choose_interpreter(self) -> Interpreter:
        """The compiled loop unless ``--kernel python``; under "auto" Python when the library is
        missing (one notice per process) or no operation has a C form, saying why."""
        if self.kernel_requested == "python":
            return self._python
        lib, reason = native.library()
        if lib is None:
            _notice_once(reason)
            self.kernel_reason = reason
            return self._python
        in_python = self.program.python_operations()
        if self.kernel_requested == "auto" and sum(in_python.values()) == len(self.program.top_level()):
            self.kernel_reason = "no operation of the step has a C form: " + "; ".join(in_python)
            return self._python
        sources = [(ty.address(buf, 0), n, ty.integer) for ty in self.buffers if not ty.strings
                   for buf, n in ((ty.Ybuf, len(ty.Y)), (ty.Ubuf, len(ty.U)))]
        self.kernel = "native"
        return NativeInterpreter(self.program, self.grid, self._python, sources, self.threads)

    def recorder_sources(self) -> tuple[list[str], list[np.ndarray]]:
        """The recorded signals' names and the arrays that hold them, in the order rows are
        written (each type's outputs, then its inputs)."""
        names, arrays = [], []
        for ty in self.buffers:
            if ty.strings:
                continue
            names += ty.out_names + ty.in_names
            arrays += [ty.Y, ty.U]
        return names, arrays

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
        self._python.exchange(t0)
        for name, inst in self.instances.items():
            self._guard(name, t0, "exiting initialization mode", inst.exit_initialization_mode)
        self._python.exchange(t0)

    def _read_input_starts(self, t0: float) -> None:
        """Unconnected inputs keep the FMU's (or the binding's) start value: every input is read
        into the input buffers before the first exchange."""
        for comp in self.order:
            inst = self.instances[comp]
            for ty in self.buffers:
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
        if self._interpreter is not None:
            self._interpreter.close()
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
        if self.loop_solver is not None:
            return self.loop_solver.metadata()
        if self.plan.algebraic_loops:
            return {"mode": "delay", "loops": [loop.describe() for loop in self.plan.algebraic_loops]}
        return None

    def metadata(self) -> dict:
        """How the run went and ran: algorithm, interpreter (``kernel``, and ``python_operations``
        or ``kernel_reason``), threads, loops, grid, status, components, reuse and parameters."""
        program = self.program
        in_python = program.python_operations() if program is not None and self.kernel == "native" else {}
        kernel = {"kernel": self.kernel} | ({"kernel_reason": self.kernel_reason} if self.kernel_reason else {}) \
            | ({"python_operations": in_python} if in_python else {}) \
            | ({"threads": self.threads, "parallel_components": list(program.parallel_components),
                "serial_components": dict(program.serial)} if self.threads > 1 and program is not None else {})
        return {
            "algorithm": self.algorithm, **kernel,
            "gauss_seidel_order": self.plan.gauss_seidel_order if self.algorithm == "gauss-seidel" else None,
            "feedthrough_sequence": self.plan.feedthrough_sequence,
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
