"""Input tables (``--input-file``) bound to a plan: which input each column drives
(`cosim.model.structure.BoundTable`, held by the plan), as ``fmpy simulate`` names them.

The table is one more source of the system: at every communication point (and during
initialisation) it sets the inputs it names, after the outputs are read and the connections
routed, with the inputs the connections set, so nothing else of the run changes
(`cosim.run.feed`).  As in fmpy's results, the outputs recorded at t are those before the table's
values at t are set: an output with direct feedthrough from a table-driven input shows that
input's value of the communication point before.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import SetupError, did_you_mean
from ..model.fmu import Variable, describe_shape, element_names, exchange_type
from ..model.structure import BoundTable, ParameterValue, Plan, SystemStructure, Target
from ..read.inputs import InputTable

#: the exchange types a table can set
NUMERIC = ("Real", "Integer", "Boolean")


def with_table(plan: Plan, bound: BoundTable) -> Plan:
    """The plan with ``bound`` feeding its inputs: a component the table drives has its inputs
    set at every exchange (not only in the settling, `cosim.model.structure.Plan.set_in_settling_only`)."""
    driven = {t.component for t in bound.targets}
    return replace(plan, input_table=bound, set_in_settling_only=plan.set_in_settling_only - driven)


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
        name = _element_of_array_column(plan, table, name, single, where)
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
            targets.append(Target(column, comp, var, tuple(values.tolist())))
    return BoundTable(table.file, tuple(table.time.tolist()), tuple(targets))


def _element_of_array_column(plan: Plan, table: InputTable, name: str, single: str | None, where: dict) -> str:
    """The element a value of a whole-array column drives (``u`` = ``1 2`` as fmusim writes it, read
    as ``u[1]``, ``u[2]``: `cosim.read.inputs.InputTable.arrays`): the k-th in the array's order,
    named as its shape names it (``A[2,1]``); ``name`` itself for any other column.  An array of
    another size than the column's is refused."""
    column, _, position = name.partition("[")
    if column not in table.arrays:
        return name
    owners = [(single, "", column)] if single is not None else []
    owners += [(c, c + ".", column[len(c) + 1:]) for c in plan.components if column.startswith(c + ".")]
    for comp, prefix, array in owners:
        var = plan.fmus[comp].variables.get(array)
        if var is not None and var.dimensions:
            shape = plan.fmus[comp].shape(var, where["element"], table.file)
            if math.prod(shape) != table.arrays[column]:
                raise SetupError(f"the column '{column}' holds {table.arrays[column]} values per row; {comp}.{array} "
                                 f"is {describe_shape(shape)}.", **(where | {"variable": column}))
            return prefix + element_names(array, shape)[int(position[:-1]) - 1]
    return name


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
