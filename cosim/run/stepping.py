"""A run from start to stop on an interpreter of the step's program (`cosim.run.interpreters`),
and what the FMI statuses the interpreters hand back mean for it.

An interpreter returns at an operation whose FMI status is above Warning; `Stepping` decides:

* a get or set: the run fails (`cosim.run.instances.base.fmi_failure`), reported at the end of the
  step (at its start for Gauss–Seidel's routes and sets before a doStep);
* a doStep that returned Discard (or FMI 3.0 terminateSimulation, turned into Discard by the
  instance's post-step): when the FMU's outputs are valid at the end of the step
  (fmi2LastSuccessfulTime = t + h, or an FMI 3.0 step that completed) the component has ended the
  run there, the other components still step and that communication point is recorded (status
  "terminated"); otherwise the run ends now at the last good time ("discarded");
* a doStep's Error or Fatal: the run fails;

and then the interpreter resumes the step at the operation after it.  A stop request (a signal,
`cosim.run.interrupts`) ends the run at the communication point just recorded ("interrupted" or
"timeout"); progress is reported every 1/200 of the run.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..model.grid import Grid
from .instances.base import fmi_failure
from .interpreters import STATUS, STOP, Event, Interpreter
from .interrupts import StopRequest
from ..record.observers import Recorder
from .link import LinkedProgram
from .program import OP_STEP

FMI_WARNING, FMI_DISCARD = 1, 2


@dataclass(frozen=True)
class Ending:
    """How a run ended: ``status`` (completed, terminated, discarded, interrupted, timeout) and
    the message that says why, if not completed."""
    status: str
    message: str = ""


class Stepping:
    """Steps ``program`` from start to stop of ``grid`` on ``interpreter`` (see the module docstring)."""

    def __init__(self, program: LinkedProgram, grid: Grid, interpreter: Interpreter):
        self.program, self.grid, self.interpreter = program, grid, interpreter

    @property
    def last_time(self) -> float:
        """The last communication point recorded."""
        return self.grid.time(self.interpreter.k)

    def run(self, recorder: Recorder, progress=None, stop: StopRequest | None = None) -> Ending:
        """Every step into ``recorder``, ``progress`` told every 1/200 of the run, until stop time,
        an FMU that ends the run, or ``stop``: how the run ended (a failed call raises)."""
        stop = stop or StopRequest()
        interpreter, time = self.interpreter, self.grid.time
        n_steps = self.grid.steps
        stride = max(1, n_steps // 200) if progress is not None else n_steps  # progress every 1/200 of the run
        ended: list[tuple[str, str]] = []
        k = first = 0
        interpreter.start(recorder, stop)
        try:
            for block in range(0, n_steps, stride):
                end = min(block + stride, n_steps)
                while k < end:
                    event = interpreter.advance(k, k + 1 if ended else end, first)
                    k, first = event.k, 0
                    if event.reason == STATUS:
                        discarded = self._on_status(event, ended)
                        if discarded is not None:
                            return discarded
                        first = self.program.operations[event.op].next
                        continue
                    if ended:
                        return self._terminated(ended, time(k))
                    if event.reason == STOP:
                        return Ending(stop.status(), f"stopped by {stop.describe()} at t = {time(k):g}.")
                if progress is not None:
                    progress.update(end - block)
            return Ending("completed")
        finally:
            interpreter.finish()

    def _on_status(self, event: Event, ended: list[tuple[str, str]]) -> Ending | None:
        """After an operation's status above Warning: raises for a failed call; records a
        component that ended the run with valid outputs in ``ended`` (the step goes on); the
        Ending of a run a Discard ends now."""
        op = self.program.operations[event.op]
        t, t_next = self.grid.time(event.k), self.grid.time(event.k + 1)
        h = t_next - t
        if op.kind != OP_STEP:
            raise op.failure(event.status, op.time(t, t_next))
        status, inst = event.status, op.instance
        if status <= FMI_WARNING:
            return None
        if status != FMI_DISCARD:
            raise fmi_failure(inst, "DoStep", status, t)
        valid_until, reason = inst.step_end(t, h)
        if valid_until is not None and math.isclose(valid_until, t + h, rel_tol=1e-12, abs_tol=1e-12):
            ended.append((op.component, reason))
            return None
        return Ending("discarded", f"component '{op.component}' ({inst.desc.path.name}): {reason} at t = {t:g} "
                                   f"(step {h:g}); the run ended at the last good time {self.last_time:g}."
                                   f"{inst.last_messages()}")

    def _terminated(self, ended: list[tuple[str, str]], t_end: float) -> Ending:
        """FMUs ended the run after a step whose outputs are valid: that point is recorded."""
        insts = {op.component: op.instance for op in self.program.operations if op.kind == OP_STEP}
        return Ending("terminated", "; ".join(f"component '{comp}' ({insts[comp].desc.path.name}): {reason} at "
                                              f"t = {t_end:g}" for comp, reason in ended)
                      + f"; the run ended there, that point recorded (stop time {self.grid.stop:g}).")
