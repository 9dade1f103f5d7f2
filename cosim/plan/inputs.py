"""Input tables (``--input-file``): a CSV that drives inputs by name, as ``fmpy simulate`` reads it.

The file is fmpy's format: a header row whose first column is ``time``, then one column per
input, one row per sample, times non-decreasing.  A time written on two rows is an event: the
first row is the value just before it, the last the value from then on.  The table is one more
source of the system: at every communication point (and during initialisation) it sets the
inputs it names, after the outputs are read and the connections routed, with the inputs the
connections set, so nothing else of the run changes (`InputFeed`, called by
`cosim.run.execution.Execution`).  As in fmpy's results, the outputs recorded at t are those
before the table's values at t are set: an output with direct feedthrough from a table-driven
input shows that input's value of the communication point before.

Values follow FMI and fmpy (``fmpy.simulation.Input``):

* a continuous Real input is interpolated linearly between samples; a discrete one (Integer,
  Boolean, Enumeration, or a Real of variability discrete) holds the value of the last sample
  at or before the time;
* at an event time (a repeated time) the value from the right (the last row at that time) is
  taken, except while the FMU initialises, where it is the value from the left (the first row);
* before the first sample the first value holds, after the last the last.

A Co-Simulation master on a fixed grid sees the table at its communication points only: an
event between two of them takes effect at the next one (fmpy adds a communication point there
when the FMU can handle variable step sizes), and a Model Exchange FMU gets its inputs held over
each communication step (fmpy interpolates them within the step).
"""
from __future__ import annotations

import csv
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from math import isclose
from pathlib import Path

import numpy as np

from ..model.fmu import Variable, exchange_type
from ..errors import SetupError, did_you_mean
from ..model.structure import ParameterValue, Plan, SystemStructure

#: the Real types of FMI 2.0 and 3.0 that may be continuous
REAL_TYPES = ("Real", "Float64", "Float32")
#: the exchange types a table can set
NUMERIC = ("Real", "Integer", "Boolean")


@dataclass(frozen=True)
class InputTable:
    """A CSV input table as read: column names (after ``time``), sample times and values."""
    file: str
    names: list[str]
    time: np.ndarray
    #: one row per column, one entry per sample
    values: np.ndarray
    #: the line of the file each sample is on (for messages)
    lines: list[int]


def read_input_table(path: str | Path) -> InputTable:
    """Read and check an input CSV; a missing file, a header without ``time`` first, a repeated
    column, a row of the wrong length, a cell that is not a finite number (or true/false) and a
    time before the previous one are each a `SetupError` naming the file, column and line."""
    file = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = [(n, row) for n, row in enumerate(csv.reader(f), 1) if row and any(c.strip() for c in row)]
    except OSError as e:
        raise SetupError(f"cannot read the input table: {e.strerror}.", file=file, element="--input-file") from None
    except (UnicodeDecodeError, csv.Error) as e:
        raise SetupError(f"not a CSV text file: {e}.", file=file, element="--input-file") from None
    if not rows:
        raise SetupError("the input table is empty; it needs a header row (time, then input names) and samples.",
                         file=file, element="--input-file")
    header_line, header = rows[0]
    names = [h.strip() for h in header]
    if names[0] != "time":
        raise SetupError(f"the first column is '{names[0]}'; an input table's first column is 'time'.",
                         file=file, element=f"line {header_line}, column 1")
    for i, name in enumerate(names):
        if not name:
            raise SetupError(f"column {i + 1} has no name.", file=file, element=f"line {header_line}")
        if names.index(name) != i:
            raise SetupError(f"column '{name}' is given twice (columns {names.index(name) + 1} and {i + 1}).",
                             file=file, element=f"line {header_line}", variable=name)
    if len(rows) < 2:
        raise SetupError("the input table has a header and no samples.", file=file, element="--input-file")
    data = np.empty((len(rows) - 1, len(names)))
    lines = []
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(names):
            raise SetupError(f"{len(row)} cells; the header has {len(names)} columns.", file=file,
                             element=f"line {line}")
        for c, cell in enumerate(row):
            data[r, c] = _number(cell, file, line, names[c])
        if r and data[r, 0] < data[r - 1, 0]:
            raise SetupError(f"time {data[r, 0]:.17g} is before the time of the row before ({data[r - 1, 0]:.17g}); "
                             "times must not decrease (a time given twice is an event).", file=file,
                             element=f"line {line}, column 'time'")
        lines.append(line)
    return InputTable(file, names[1:], data[:, 0].copy(), data[:, 1:].T.copy(), lines)


def _number(cell: str, file: str, line: int, column: str) -> float:
    text = cell.strip()
    if text.lower() in ("true", "false"):
        return 1.0 if text.lower() == "true" else 0.0
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SetupError(f"'{cell}' is not a finite number.", file=file, element=f"line {line}, column '{column}'",
                         variable=column)
    return value


# --------------------------------------------------------------------------- bound to a plan

@dataclass(frozen=True)
class Target:
    """The input one column drives, and the values it gets (the column's, through a system
    connector's transformations and unit conversions where the column names one)."""
    column: int
    component: str
    variable: Variable
    values: np.ndarray

    @property
    def name(self) -> str:
        return f"{self.component}.{self.variable.name}"

    @property
    def discrete(self) -> bool:
        """Held between samples (fmpy: every input that is not a continuous Real)."""
        return not (self.variable.type in REAL_TYPES and self.variable.variability not in ("discrete", "tunable"))


def with_table(plan: Plan, bound: BoundTable) -> Plan:
    """The plan with ``bound`` feeding its inputs: a component the table drives has its inputs
    set at every exchange (not only in the settling, `cosim.model.structure.Plan.set_in_settling_only`)."""
    driven = {t.component for t in bound.targets}
    return replace(plan, input_table=bound, set_in_settling_only=plan.set_in_settling_only - driven)


@dataclass(frozen=True)
class BoundTable:
    """An input table checked against a plan: which input each column drives."""
    table: InputTable
    targets: list[Target]

    def feed(self, typed: list, grid=None) -> InputFeed:
        """The callable that sets the table's values into the exchange's input buffers
        (`cosim.run.exchange.TypedBuffers`) at a time; with the run's ``grid`` (`cosim.model.grid.Grid`),
        a `RuntimeWarning` names the table's events that fall between its communication points."""
        if grid is not None:
            off = [t for t in self.event_times() if grid.start < t < grid.stop and not _on_grid(t, grid)]
            if off:
                shown = ", ".join(f"{t:g}" for t in off[:8]) + (f" and {len(off) - 8} more" if len(off) > 8 else "")
                warnings.warn(f"{self.table.file}: input events at t = {shown} s fall between communication points "
                              f"(step {grid.step:g} s); each takes effect at the next one (fmpy adds a communication "
                              "point there for an FMU that can vary its step).", RuntimeWarning, stacklevel=2)
        return InputFeed(self, typed)

    def event_times(self) -> list[float]:
        """The table's events as fmpy finds them (``Input.findEvents``): times given twice, and the
        times a discrete input's value changes."""
        t = self.table.time
        events = set(t[np.flatnonzero(np.diff(t) == 0)].tolist())
        for target in self.targets:
            if target.discrete:
                events.update(t[np.flatnonzero(np.diff(target.values)) + 1].tolist())
        return sorted(events)


def _on_grid(t: float, grid) -> bool:
    k = round((t - grid.start) / grid.step)
    return isclose(t, grid.time(k), rel_tol=1e-9, abs_tol=1e-12 * max(1.0, abs(t)))


def connector_values(table: InputTable, structure: SystemStructure) -> list[ParameterValue]:
    """A value (the first sample) for each undriven system connector the table names, so the
    plan takes it as driven (`cosim.plan.parameters.bind_system_connectors`); the table's values
    replace it from the first exchange on."""
    return [ParameterValue(name, "Real", float(table.values[i][0]), table.file, table.lines[0])
            for i, name in enumerate(table.names) if name in structure.open_connectors]


def bind_table(table: InputTable, plan: Plan, single: str | None = None) -> BoundTable:
    """Match each column to inputs: ``component.input``, an undriven system connector of a
    system (each input it feeds, through its transformations: `cosim.model.structure.Plan.open_inputs`),
    or for a single FMU (``single``: its component) the variable's own name, as fmpy names it.  A name that is no input, an input a
    connection drives, a String or Binary input, and a value that is not of the input's type
    (an Integer that is not whole, a Boolean that is not 0 or 1) are refused, naming the file,
    column and line."""
    driven = {(r.dst, r.dst_var.name) for r in plan.routes}
    inputs = {f"{c}.{v.name}": (c, v) for c in plan.inputs for v in plan.inputs[c]}
    connectors = plan.open_inputs if single is None else {}
    targets: list[Target] = []
    for column, name in enumerate(table.names):
        where = dict(file=table.file, element=f"line {table.lines[0] - 1}, column '{name}'", variable=name)
        found = inputs.get(f"{single}.{name}") if single is not None else None
        found = found or inputs.get(name)
        if found is not None:
            fed = [(found[0], found[1], table.values[column])]
        elif name in connectors:
            fed = _through_connector(plan, table, column, where)
        else:
            _not_a_connector(plan, name, where)
            known = [n.partition(".")[2] if single else n for n in inputs] + list(connectors)
            raise SetupError("no input of that name" + (f" in {single}" if single else "; name inputs "
                             "'component.input' or a system input connector") + ".", **where,
                             hint=did_you_mean(name, known) or (f"Inputs: {', '.join(known[:12])}." if known
                                                                else "The system has no inputs."))
        for comp, var, values in fed:
            if (comp, var.name) in driven:
                raise SetupError(f"{comp}.{var.name} is driven by a connection; the table cannot drive it too.",
                                 **where)
            if exchange_type(var) not in NUMERIC:
                raise SetupError(f"{comp}.{var.name} is a {var.type} input; a table drives numeric ones.", **where)
            _check_values(table, column, var, values, where)
            if any(t.component == comp and t.variable.name == var.name for t in targets):
                raise SetupError(f"{comp}.{var.name} is driven by two columns.", **where)
            targets.append(Target(column, comp, var, values))
    return BoundTable(table, targets)


def _not_a_connector(plan: Plan, name: str, where: dict) -> None:
    """Refuse a column naming an input of a component's FMU that the SSD does not declare as a
    connector of that component (the exchange carries connectors only)."""
    for comp in sorted(plan.components, key=len, reverse=True):
        var = plan.fmus[comp].variables.get(name[len(comp) + 1:]) if name.startswith(comp + ".") else None
        if var is not None and var.causality == "input":
            raise SetupError(f"{var.name} is an input of {plan.fmus[comp].path.name} but no connector of component "
                             f"'{comp}' in the SSD.", **where,
                             hint=f'Declare it: <ssd:Connector name="{var.name}" kind="input"/>.')


def _through_connector(plan: Plan, table: InputTable, column: int,
                       where: dict) -> list[tuple[str, Variable, np.ndarray]]:
    """The inputs an undriven system connector feeds and the column's values as each gets them:
    through the connector's transformations and unit conversions (`cosim.model.structure.Plan.open_inputs`);
    a value a mapping table on the way names no target is refused, naming its line."""
    fed = []
    for comp, conn, transform in plan.open_inputs[table.names[column]]:
        values = table.values[column] if transform.identity else transform.apply_array(table.values[column])
        unmapped = np.flatnonzero(np.isnan(values))
        if len(unmapped):
            row = int(unmapped[0])
            raise SetupError(f"{table.values[column][row]:.17g} reaches {comp}.{conn} through {transform.text()}, "
                             "which names no target for it.",
                             **(where | {"element": f"line {table.lines[row]}, column '{table.names[column]}'"}))
        fed.append((comp, plan.fmus[comp].variables[conn], values))
    return fed


def _check_values(table: InputTable, column: int, var: Variable, values: np.ndarray, where: dict) -> None:
    kind = exchange_type(var)
    if kind == "Integer":
        bad = np.flatnonzero(values != np.round(values))
        what = "an Integer input: values are whole numbers"
    elif kind == "Boolean":
        bad = np.flatnonzero((values != 0) & (values != 1))
        what = "a Boolean input: values are 0, 1, true or false"
    else:
        return
    if len(bad):
        row = int(bad[0])
        raise SetupError(f"{values[row]:.17g}: {var.name} is {what}.",
                         **(where | {"element": f"line {table.lines[row]}, column '{table.names[column]}'"}))


# --------------------------------------------------------------------------- at run time

class InputFeed:
    """Writes the table's values at a time into the exchange's input buffers (``TypedBuffers.U``),
    by the buffers' input names; the first call (initialisation) takes left values at events."""

    def __init__(self, bound: BoundTable, typed: list):
        table = bound.table
        self.time = table.time
        self.initialising = True
        self.groups = []
        for ty in typed:
            if ty.strings:
                continue
            index = {n: i for i, n in enumerate(ty.in_names)}
            for discrete in (False, True):
                chosen = [t for t in bound.targets if t.name in index and t.discrete == discrete]
                if chosen:
                    self.groups.append((ty.U, np.array([index[t.name] for t in chosen], dtype=np.intp),
                                        np.stack([t.values for t in chosen]), discrete))

    def __call__(self, t: float) -> None:
        after_event = not self.initialising
        self.initialising = False
        for buffer, positions, values, discrete in self.groups:
            buffer[positions] = interpolate(t, self.time, values, discrete, after_event)


def interpolate(time: float, t: np.ndarray, table: np.ndarray, discrete: bool, after_event: bool) -> np.ndarray:
    """The values of ``table`` (one row per signal, one column per sample at times ``t``) at
    ``time``, as ``fmpy.simulation.Input.interpolate`` computes them (times compared with
    `math.isclose`)."""
    n = len(t)
    if n < 2:
        return table[:, 0]
    i0 = int(np.searchsorted(t, time))
    if i0 == 0:
        return table[:, 0]
    if i0 == n:
        return table[:, -1]
    if discrete:
        i = i0 - 1
        if after_event:
            while i + 1 < n and (t[i + 1] < time or isclose(time, t[i + 1])):
                i += 1
        return table[:, i]
    if isclose(time, t[i0]) and i0 < n - 1 and isclose(t[i0], t[i0 + 1]):  # an event at time
        if after_event:
            while i0 < n - 1 and isclose(t[i0], t[i0 + 1]):
                i0 += 1
        return table[:, i0]
    t0, t1 = t[i0 - 1], t[i0]
    w0 = (t1 - time) / (t1 - t0)
    return w0 * table[:, i0 - 1] + (1 - w0) * table[:, i0]
