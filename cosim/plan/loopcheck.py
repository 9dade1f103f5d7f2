"""Warnings where a loop changes without a word: what the FMUs' ``org.greyfmu`` annotation
(`cosim.read.annotations`) says about sampling and wiring, checked against the plan and the grid.

`loop_warnings` finds, one `LoopWarning` each, naming the component and the variable:

- a master step that is larger than a sampled component's sample time, or that does not divide
  it (or whose grid misses its first sample instant): its samples then act on inputs up to a
  step old and are seen up to a step late, or several act on the same inputs: the loop is not
  the one designed (the pid_fopdt loop with the PID at Ts = 0.1 s and a 0.25 s step: IAE and
  settling time change, issue 45);
- an input the FMU's law reads (set-point, measurement, scheduling or process input) that no
  connection, parameter binding, ``--start-value`` or input table gives a value: it keeps its
  start value for the whole run;
- a sample time left at the FMU's default (no binding sets it) that is not the master step: a
  controller swapped in for another samples at its own default (PID 0.1 s, GrayPredictivePI 1 s).

`check_loops` issues them as warnings (the CLI prints each as one ``cosim: warning:`` line);
``--strict`` turns `cosim.errors.CosimWarning`, their base, into errors (exit 2).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

from ..errors import CosimWarning
from ..model.grid import Grid
from ..model.structure import Plan
from ..read.annotations import loop_annotation

#: relative tolerance of "the step divides the sample time" (the grid is computed, t_k = t0 + k·h)
_TOLERANCE = 1e-9


class LoopWarning(CosimWarning):
    """A loop that runs, but not as its FMUs were designed to run in it."""


@dataclass(frozen=True)
class Finding:
    component: str
    variable: str
    message: str


def _multiple(ratio: float) -> bool:
    return abs(ratio - round(ratio)) <= _TOLERANCE * max(1.0, abs(ratio))


def loop_warnings(plan: Plan, grid: Grid) -> list[Finding]:
    """The findings of the module docstring, component by component in SSD order."""
    applied = {(sv.component, sv.variable.name): sv.value for sv in plan.start_values}
    connected = {(route.dst, route.dst_var.name) for route in plan.routes}
    table = getattr(plan.input_table, "targets", ()) or ()
    fed = {(target.component, target.variable.name) for target in table}
    found = []
    for name, desc in plan.fmus.items():
        facts = loop_annotation(desc.path)
        if facts is None:
            continue
        fmu = desc.path.name

        def value(parameter: str):
            return applied.get((name, parameter), desc.variables[parameter].start
                               if parameter in desc.variables else None)

        if facts.sample_time is not None and facts.sample_time in desc.variables:
            found += _sampling(name, fmu, facts.sample_time, facts.sample_offset, value,
                               (name, facts.sample_time) in applied, grid)
        for port in facts.ports:
            key = (name, port.name)
            if port.required(value) and key not in connected | fed and key not in applied:
                condition = f" ({port.when.split()[0]} = {_text(value(port.when.split()[0]))})" if port.when else ""
                start = desc.variables[port.name].start if port.name in desc.variables else None
                found.append(Finding(name, port.name, f"{name}.{port.name} is not connected: {fmu} reads it as its "
                                     f"{port.role} input{condition}; it keeps its start value {start} for the whole "
                                     "run. Connect it, or bind a value to it to keep it constant."))
    return found


def _sampling(name: str, fmu: str, parameter: str, offset: str | None, value, bound: bool, grid: Grid) -> list[Finding]:
    """The sample-time findings of one component (`loop_warnings`)."""
    try:
        ts = float(value(parameter))
    except (TypeError, ValueError):
        return []
    if not (math.isfinite(ts) and ts > 0):
        return []   # the FMU refuses it at initialisation, naming it
    h, full = grid.step, f"{name}.{parameter}"
    found = []
    if h > ts * (1 + _TOLERANCE):
        found.append(Finding(name, parameter, f"the master step {h:g} s is longer than {full} = {ts:g} s: {fmu} "
                             f"makes up to {math.ceil(h / ts)} samples per step from the same inputs, so the loop is "
                             f"sampled every {h:g} s, not {ts:g} s. Use --step {ts:g} (or a divisor of it)."))
    elif not _multiple(ts / h):
        better = ts / math.ceil(ts / h)
        found.append(Finding(name, parameter, f"the master step {h:g} s does not divide {full} = {ts:g} s: {fmu}'s "
                             f"samples fall inside communication steps, act on inputs up to {h:g} s old and are seen "
                             f"up to {h:g} s late. Use a step that divides {ts:g} s (e.g. --step {better:g})."))
    elif offset is not None:
        try:
            first = float(value(offset))
        except (TypeError, ValueError):
            first = grid.start
        if math.isfinite(first) and first > grid.start and not _multiple((first - grid.start) / h):
            found.append(Finding(name, offset, f"{name}.{offset} = {first:g} s, {fmu}'s first sample, is not on the "
                                 f"master grid (start {grid.start:g} s, step {h:g} s): every sample falls inside a "
                                 "communication step."))
    if not bound and not math.isclose(ts, h, rel_tol=_TOLERANCE):
        found.append(Finding(name, parameter, f"{full} = {ts:g} s is {fmu}'s default (no parameter binding sets it), "
                             f"not the master step {h:g} s: a controller swapped in for another samples at its own "
                             f"default. Bind {full} in the scenario to choose the loop's sampling."))
    return found


def _text(value) -> str:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return f"{number:g}"


def check_loops(plan: Plan, grid: Grid) -> None:
    """Issue each of `loop_warnings` as a `LoopWarning` (an error where ``--strict`` made them one)."""
    for finding in loop_warnings(plan, grid):
        warnings.warn(finding.message, LoopWarning, stacklevel=2)
