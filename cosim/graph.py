"""Validate a system structure against its FMUs and order its evaluation.

Everything here runs before any FMU is instantiated.  `build_plan` checks the
connectors, connections and parameter values against each FMU's model
description, detects direct-feedthrough (algebraic) loops from the FMI 2.0
ModelStructure, and returns a `Plan`: the routes and the orders the execution
follows.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

from fmpy.model_description import ModelVariable

from .errors import SetupError, did_you_mean
from .fmu import FMUDescription, describe, unit_of
from .ssp import Connection, ParameterValue, SystemStructure

SUPPORTED_TYPES = ("Real", "Integer", "Boolean")
SETTABLE_CAUSALITIES = ("parameter", "input")


@dataclass
class Route:
    """One connection, resolved: output (src) to input (dst), with its linear transformation."""
    src: str
    src_var: ModelVariable
    dst: str
    dst_var: ModelVariable
    factor: float
    offset: float


@dataclass
class StartValue:
    component: str
    variable: ModelVariable
    value: float | int | bool | str
    origin: str


@dataclass
class Plan:
    structure: SystemStructure
    fmus: dict[str, FMUDescription]
    routes: list[Route]
    start_values: list[StartValue]
    #: per component, the connector variables recorded and exchanged, in SSD order
    outputs: dict[str, list[ModelVariable]]
    inputs: dict[str, list[ModelVariable]]
    #: components whose outputs must be re-read after their inputs are set at a
    #: communication point (direct feedthrough), in dependency order; may repeat
    feedthrough_sequence: list[str]
    #: Gauss-Seidel order: upstream first, SSD order inside a loop
    gauss_seidel_order: list[str]
    notes: list[str] = field(default_factory=list)


def build_plan(structure: SystemStructure, extra_parameters: list[ParameterValue] = ()) -> Plan:
    """Check the structure against the FMUs (already located) and order it."""
    file = str(structure.ssd_file)
    fmus = {name: describe(comp.fmu_path, f"ssd:Component '{name}' (line {comp.line})", file)
            for name, comp in structure.components.items()}
    outputs, inputs = _check_connectors(structure, fmus)
    routes = _check_connections(structure, fmus)
    start_values = _check_parameters(structure, fmus, list(extra_parameters))
    order = _variable_order(structure, fmus, routes, outputs)
    feedthrough = _feedthrough_sequence(order, fmus, routes)
    return Plan(structure=structure, fmus=fmus, routes=routes, start_values=start_values,
                outputs=outputs, inputs=inputs, feedthrough_sequence=feedthrough,
                gauss_seidel_order=_gauss_seidel_order(structure, routes))


# --------------------------------------------------------------------------- connectors

def _check_connectors(structure: SystemStructure, fmus: dict[str, FMUDescription]):
    file = str(structure.ssd_file)
    outputs: dict[str, list[ModelVariable]] = {}
    inputs: dict[str, list[ModelVariable]] = {}
    for name, comp in structure.components.items():
        desc = fmus[name]
        outputs[name], inputs[name] = [], []
        for conn in comp.connectors.values():
            where = f"ssd:Connector '{conn.name}' of component '{name}' (line {conn.line})"
            var = desc.variable(conn.name, where, file)
            if conn.kind in ("input", "output") and var.causality != conn.kind:
                raise SetupError(f"declared kind='{conn.kind}' but the FMU {desc.path.name} declares it "
                                 f"causality='{var.causality}'.", file=file, element=where, variable=conn.name)
            if conn.type is not None and conn.type != var.type:
                raise SetupError(f"declared as {conn.type} but the FMU {desc.path.name} declares {var.type}.",
                                 file=file, element=where, variable=conn.name)
            if var.causality in ("input", "output") and var.type not in SUPPORTED_TYPES:
                raise SetupError(f"{var.type} connectors are not supported (Real, Integer, Boolean are).",
                                 file=file, element=where, variable=conn.name)
            if conn.unit is not None and unit_of(var) is not None and conn.unit != unit_of(var):
                raise SetupError(f"declared unit '{conn.unit}' differs from the FMU's '{unit_of(var)}'; unit "
                                 "conversion is not implemented.", file=file, element=where, variable=conn.name)
            if var.causality == "output":
                outputs[name].append(var)
            elif var.causality == "input":
                inputs[name].append(var)
    return outputs, inputs


def _check_connections(structure: SystemStructure, fmus: dict[str, FMUDescription]):
    file = str(structure.ssd_file)
    routes: list[Route] = []
    driven: dict[tuple[str, str], Connection] = {}
    for c in structure.connections:
        where = c.describe()
        a = _endpoint(structure, fmus, c.start_element, c.start_connector, where)
        b = _endpoint(structure, fmus, c.end_element, c.end_connector, where)
        # SSP 1.0: data flows from output to input whatever the start/end naming
        if a.causality == "output" and b.causality == "input":
            (src, sv), (dst, dv) = (c.start_element, a), (c.end_element, b)
        elif a.causality == "input" and b.causality == "output":
            (src, sv), (dst, dv) = (c.end_element, b), (c.start_element, a)
        elif a.causality == b.causality == "output":
            raise SetupError(f"output wired to output ({c.start_element}.{a.name} and {c.end_element}.{b.name}); "
                             "a connection goes from an output to an input.", file=file, element=where)
        elif a.causality == b.causality == "input":
            raise SetupError(f"input wired to input ({c.start_element}.{a.name} and {c.end_element}.{b.name}); "
                             "a connection goes from an output to an input.", file=file, element=where)
        else:
            bad = a if a.causality not in ("input", "output") else b
            raise SetupError(f"'{bad.name}' has causality '{bad.causality}'; only outputs wired to inputs "
                             "are supported.", file=file, element=where, variable=bad.name)
        if sv.type != dv.type:
            raise SetupError(f"{sv.type} output {src}.{sv.name} wired to {dv.type} input {dst}.{dv.name}; "
                             "both ends must have the same type.", file=file, element=where)
        if c.has_transformation and sv.type != "Real":
            raise SetupError("a LinearTransformation applies to Real connections only; "
                             f"this one is {sv.type}.", file=file, element=where)
        us, ud = unit_of(sv), unit_of(dv)
        if us and ud and us != ud and not c.suppress_unit_conversion:
            raise SetupError(f"units differ ({src}.{sv.name} in '{us}', {dst}.{dv.name} in '{ud}') and unit "
                             "conversion is not implemented; add suppressUnitConversion=\"true\" with an "
                             "ssc:LinearTransformation that converts.", file=file, element=where)
        key = (dst, dv.name)
        if key in driven:
            raise SetupError(f"input {dst}.{dv.name} is driven by two connections (the other: "
                             f"{driven[key].describe()}).", file=file, element=where, variable=dv.name)
        driven[key] = c
        routes.append(Route(src, sv, dst, dv, c.factor, c.offset))
    return routes


def _endpoint(structure: SystemStructure, fmus: dict[str, FMUDescription], element: str, connector: str,
              where: str) -> ModelVariable:
    file = str(structure.ssd_file)
    if element not in structure.components:
        raise SetupError(f"unknown component '{element}'.", file=file, element=where,
                         hint=did_you_mean(element, structure.components))
    comp = structure.components[element]
    if connector not in comp.connectors:
        var = fmus[element].variables.get(connector)
        if var is not None:
            raise SetupError(f"'{connector}' is a variable of {fmus[element].path.name} but not a declared "
                             f"connector of component '{element}'.", file=file, element=where,
                             variable=connector, hint=f"Add <ssd:Connector name=\"{connector}\" "
                             f"kind=\"{var.causality}\"/> to its ssd:Connectors.")
        raise SetupError(f"component '{element}' has no connector '{connector}'.", file=file, element=where,
                         variable=connector, hint=did_you_mean(connector, comp.connectors))
    return fmus[element].variable(connector, where, file)


# --------------------------------------------------------------------------- parameters

def _check_parameters(structure: SystemStructure, fmus: dict[str, FMUDescription],
                      extra: list[ParameterValue]) -> list[StartValue]:
    """Component bindings, then system bindings, then extra (command-line) sets: later wins."""
    resolved: dict[tuple[str, str], StartValue] = {}
    for name, comp in structure.components.items():
        for p in comp.parameters:
            _apply_parameter(resolved, name, p.name, p, fmus[name])
    for p in list(structure.parameters) + extra:
        comp_name, var_name = _split_system_name(structure, p)
        _apply_parameter(resolved, comp_name, var_name, p, fmus[comp_name])
    return list(resolved.values())


def _split_system_name(structure: SystemStructure, p: ParameterValue) -> tuple[str, str]:
    for comp in sorted(structure.components, key=len, reverse=True):
        if p.name.startswith(comp + "."):
            return comp, p.name[len(comp) + 1:]
    raise SetupError(f"system-level parameter '{p.name}' does not start with a component name "
                     "('component.variable').", file=p.file, element=f"ssv:Parameter (line {p.line})",
                     variable=p.name, hint=did_you_mean(p.name.split(".")[0], structure.components))


def _apply_parameter(resolved: dict, comp: str, var_name: str, p: ParameterValue, desc: FMUDescription) -> None:
    where = f"ssv:Parameter '{p.name}' (line {p.line}) for component '{comp}'"
    var = desc.variable(var_name, where, p.file)
    if var.causality not in SETTABLE_CAUSALITIES or var.variability == "constant":
        raise SetupError(f"'{var_name}' has causality '{var.causality}' and variability '{var.variability}'; "
                         "only parameters and inputs (non-constant) can be given values.",
                         file=p.file, element=where, variable=var_name)
    value = _coerce(p, var, where)
    if var.type == "Real" or var.type == "Integer":
        lo = float(var.min) if var.min is not None else None
        hi = float(var.max) if var.max is not None else None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise SetupError(f"value {value} is outside the variable's range [{var.min}, {var.max}] "
                             f"declared by {desc.path.name}.", file=p.file, element=where, variable=var_name)
    resolved[(comp, var_name)] = StartValue(comp, var, value, f"{p.file}:{p.line}")


def _coerce(p: ParameterValue, var: ModelVariable, where: str):
    if var.type == p.type:
        return p.value
    if var.type == "Real" and p.type == "Integer":
        return float(p.value)
    if var.type == "Integer" and p.type == "Real" and float(p.value).is_integer():
        return int(p.value)
    raise SetupError(f"a {p.type} value ({p.value}) is given for a {var.type} variable.", file=p.file,
                     element=where, variable=var.name)


# --------------------------------------------------------------------------- ordering

def _variable_order(structure: SystemStructure, fmus: dict[str, FMUDescription], routes: list[Route],
                    outputs: dict[str, list[ModelVariable]]) -> list[tuple[str, str, str]]:
    """Topological order of connected variables and output connectors; a direct-feedthrough
    cycle is an error.

    Nodes are ('out'|'in', component, variable); edges go along connections and,
    inside a component, from a connected input to each output that depends on it.
    """
    edges: dict[tuple, list[tuple]] = defaultdict(list)
    nodes: list[tuple] = []
    connected_in: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        a, b = ("out", r.src, r.src_var.name), ("in", r.dst, r.dst_var.name)
        edges[a].append(b)
        nodes += [a, b]
        connected_in[r.dst].add(r.dst_var.name)
    for comp, variables in outputs.items():
        for var in variables:
            out = ("out", comp, var.name)
            nodes.append(out)
            for dep in fmus[comp].output_dependencies.get(var.name, []):
                if dep in connected_in[comp]:
                    edges[("in", comp, dep)].append(out)
    nodes = list(dict.fromkeys(nodes))
    cycles = [scc for scc in _tarjan(nodes, edges) if len(scc) > 1]
    if cycles:
        text = "; ".join(" -> ".join(f"{c}.{v} ({k}put)" for k, c, v in _cycle_path(scc, edges))
                         for scc in cycles)
        raise SetupError("algebraic loop: these variables depend on each other at the same instant "
                         f"through direct feedthrough: {text}. Break the loop with a component that has "
                         "no direct feedthrough (a delay or a filter), or check the FMUs' ModelStructure "
                         "dependencies.", file=str(structure.ssd_file), element="ssd:Connections")
    return _topological(nodes, edges)


def _tarjan(nodes: list, edges: dict) -> list[list]:
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    result: list[list] = []
    counter = [0]

    def visit(v):  # recursion depth is bounded by the number of connected variables
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                scc.append(w)
                if w == v:
                    break
            result.append(scc[::-1])

    for v in nodes:
        if v not in index:
            visit(v)
    return result


def _cycle_path(scc: list, edges: dict) -> list:
    """Order an SCC's nodes along its edges so the message reads as a loop."""
    members = set(scc)
    path = [scc[0]]
    seen = {scc[0]}
    while True:
        nxt = next((w for w in edges.get(path[-1], []) if w in members and w not in seen), None)
        if nxt is None:
            break
        path.append(nxt)
        seen.add(nxt)
    path += [n for n in scc if n not in seen]
    return path + [path[0]]


def _topological(nodes: list, edges: dict) -> list:
    indegree = {n: 0 for n in nodes}
    for v in nodes:
        for w in edges.get(v, []):
            indegree[w] += 1
    ready = [n for n in nodes if indegree[n] == 0]
    order = []
    while ready:
        v = ready.pop(0)
        order.append(v)
        for w in edges.get(v, []):
            indegree[w] -= 1
            if indegree[w] == 0:
                ready.append(w)
    return order


def _feedthrough_sequence(order: list, fmus: dict[str, FMUDescription], routes: list[Route]) -> list[str]:
    """Components whose connected outputs depend on connected inputs, in dependency order."""
    connected_in: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        connected_in[r.dst].add(r.dst_var.name)
    sequence: list[str] = []
    for kind, comp, var in order:
        if kind != "out":
            continue
        if set(fmus[comp].output_dependencies.get(var, [])) & connected_in[comp]:
            if not sequence or sequence[-1] != comp:
                sequence.append(comp)
    return sequence


def _gauss_seidel_order(structure: SystemStructure, routes: list[Route]) -> list[str]:
    """Components upstream first (SCCs of the connection graph in topological order)."""
    names = list(structure.components)
    edges: dict[str, list[str]] = defaultdict(list)
    for r in routes:
        if r.dst not in edges[r.src]:
            edges[r.src].append(r.dst)
    sccs = _tarjan(names, edges)
    position = {n: i for i, n in enumerate(names)}
    scc_of = {n: i for i, scc in enumerate(sccs) for n in scc}
    dag: dict[int, list[int]] = defaultdict(list)
    for a, targets in edges.items():
        for b in targets:
            if scc_of[a] != scc_of[b] and scc_of[b] not in dag[scc_of[a]]:
                dag[scc_of[a]].append(scc_of[b])
    scc_order = _topological(sorted(range(len(sccs)), key=lambda i: min(position[n] for n in sccs[i])), dag)
    return [n for i in scc_order for n in sorted(sccs[i], key=position.get)]
