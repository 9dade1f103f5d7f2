"""The orders a plan follows, from the connection graph alone: no FMU is read here.

* `algebraic_loops`: the direct-feedthrough cycles (Tarjan's strongly connected components);
* `variable_order`: connected variables in dependency order, the dependencies inside the
  given loops left out (a cycle left is refused);
* `feedthrough_sequence`: the components to settle at each communication point;
* `settling_shortcuts`: the FMI calls the exchange may leave out while settling;
* `gauss_seidel_order`: components upstream first, SSD order inside a loop.

The inputs are names: components, variables, and each component's output dependencies
(FMI 2.0 ModelStructure, `cosim.model.fmu.FMUDescription.output_dependencies`).
"""
from __future__ import annotations

from collections import defaultdict, deque
from collections.abc import Collection, Hashable, Mapping, Sequence

from ..errors import SetupError
from ..model.structure import AlgebraicLoop, Route

#: A node of the variable graph: ("out" | "in", component, variable).
Variable = tuple[str, str, str]
#: Per component, the inputs each output depends on at the same instant.
Dependencies = Mapping[str, Mapping[str, Sequence[str]]]


def _variable_graph(routes: Sequence[Route], outputs: Mapping[str, Sequence[str]], dependencies: Dependencies,
                    cut: Collection[AlgebraicLoop] = ()) -> tuple[list[Variable], dict[Variable, list[Variable]]]:
    """Nodes ('out'|'in', component, variable) and edges: along connections and, inside a
    component, from a connected input to each output that depends on it, except the
    dependencies inside the loops ``cut``."""
    edges: dict[Variable, list[Variable]] = defaultdict(list)
    nodes: list[Variable] = []
    connected_in = _connected_inputs(routes)
    inside = [loop.variables for loop in cut]
    for r in routes:
        a, b = ("out", r.src, r.src_var.name), ("in", r.dst, r.dst_var.name)
        edges[a].append(b)
        nodes += [a, b]
    for comp, names in outputs.items():
        for name in names:
            out = ("out", comp, name)
            nodes.append(out)
            if not connected_in[comp]:   # (a single FMU: every element of an output array on every input's)
                continue
            for dep in dependencies[comp].get(name, []):
                source = ("in", comp, dep)
                if dep in connected_in[comp] and not (inside and any(source in v and out in v for v in inside)):
                    edges[source].append(out)
    return list(dict.fromkeys(nodes)), edges


def algebraic_loops(routes: Sequence[Route], outputs: Mapping[str, Sequence[str]],
                    dependencies: Dependencies) -> list[AlgebraicLoop]:
    """The direct-feedthrough cycles of the variable graph (Tarjan's strongly connected
    components with more than one variable), each with one cycle through it for messages."""
    nodes, edges = _variable_graph(routes, outputs, dependencies)
    return [AlgebraicLoop(tuple(cycle_path(scc, edges)), frozenset(scc))
            for scc in tarjan(nodes, edges) if len(scc) > 1][::-1]


def variable_order(routes: Sequence[Route], outputs: Mapping[str, Sequence[str]], dependencies: Dependencies,
                   file: str, cut: Collection[AlgebraicLoop] = ()) -> list[Variable]:
    """Topological order of connected variables and output connectors, with the
    dependencies inside the loops ``cut`` left out; a remaining direct-feedthrough cycle is
    an error."""
    nodes, edges = _variable_graph(routes, outputs, dependencies, cut)
    cycles = [scc for scc in tarjan(nodes, edges) if len(scc) > 1]
    if cycles:
        text = "; ".join(" -> ".join(f"{c}.{v} ({k}put)" for k, c, v in cycle_path(scc, edges))
                         for scc in cycles)
        raise SetupError("algebraic loop: these variables depend on each other at the same instant "
                         f"through direct feedthrough: {text}. Break the loop with a component that has "
                         "no direct feedthrough (a delay or a filter), or check the FMUs' ModelStructure "
                         "dependencies.", file=file, element="ssd:Connections")
    return topological(nodes, edges)


def _connected_inputs(routes: Sequence[Route]) -> dict[str, set[str]]:
    connected: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        connected[r.dst].add(r.dst_var.name)
    return connected


def tarjan(nodes: Sequence[Hashable], edges: Mapping) -> list[list]:
    """Tarjan's strongly connected components of the graph ``edges`` (node -> successors),
    each in the order its nodes were visited, components in reverse topological order."""
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    result: list[list] = []

    for root in nodes:  # iterative (a 10 000-FMU chain is deeper than Python's recursion limit)
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(edges.get(root, [])))]
        while work:
            v, successors = work[-1]
            for w in successors:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges.get(w, []))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:  # every successor of v done
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[v])
                if low[v] == index[v]:
                    scc = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        scc.append(w)
                        if w == v:
                            break
                    result.append(scc[::-1])
    return result


def cycle_path(scc: Sequence, edges: Mapping) -> list:
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


def topological(nodes: Sequence, edges: Mapping) -> list:
    """Kahn's order of an acyclic graph: ties in the order of ``nodes``."""
    indegree = {n: 0 for n in nodes}
    for v in nodes:
        for w in edges.get(v, []):
            indegree[w] += 1
    ready = deque(n for n in nodes if indegree[n] == 0)
    order = []
    while ready:
        v = ready.popleft()
        order.append(v)
        for w in edges.get(v, []):
            indegree[w] -= 1
            if indegree[w] == 0:
                ready.append(w)
    return order


def feedthrough_sequence(order: Sequence[Variable], routes: Sequence[Route],
                         dependencies: Dependencies) -> list[str]:
    """Components whose connected outputs depend on connected inputs, in dependency order."""
    connected_in = _connected_inputs(routes)
    sequence: list[str] = []
    for kind, comp, var in order:
        if kind != "out":
            continue
        if connected_in[comp] and not connected_in[comp].isdisjoint(dependencies[comp].get(var, ())):
            if not sequence or sequence[-1] != comp:
                sequence.append(comp)
    return sequence


def settling_shortcuts(sequence: Sequence[str], routes: Sequence[Route]) -> tuple[set[str], set[str]]:
    """FMI calls the exchange can leave out without changing a value.

    The exchange reads every output, then settles the feedthrough sequence (set a
    component's inputs, re-read its outputs), then sets every input.  A component F of the
    sequence need not be read first when every component that reads F inside the sequence
    comes after F's first place in it (F's own loop-back counts as reading it first); a
    component X need not be set at the end when every source of X in the sequence has its
    last place before X's last place (X was set with final values).  A chain of feedthrough
    blocks then costs one set and one get per block instead of two of each.
    """
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    for i, comp in enumerate(sequence):
        first.setdefault(comp, i)
        last[comp] = i
    consumers: dict[str, set[str]] = defaultdict(set)
    sources: dict[str, set[str]] = defaultdict(set)
    for r in routes:
        consumers[r.src].add(r.dst)
        sources[r.dst].add(r.src)
    read_once = {f for f in first if all(first[x] > first[f] for x in consumers[f] if x in first)}
    set_once = {x for x in last if all(last[s] < last[x] for s in sources[x] if s in last)}
    return read_once, set_once


def gauss_seidel_order(components: Sequence[str], routes: Sequence[Route]) -> list[str]:
    """Components upstream first (SCCs of the connection graph in topological order), SSD
    order (the order of ``components``) inside a loop and between independent parts."""
    names = list(components)
    edges: dict[str, list[str]] = defaultdict(list)
    for r in routes:
        if r.dst not in edges[r.src]:
            edges[r.src].append(r.dst)
    sccs = tarjan(names, edges)
    position = {n: i for i, n in enumerate(names)}
    scc_of = {n: i for i, scc in enumerate(sccs) for n in scc}
    dag: dict[int, list[int]] = defaultdict(list)
    for a, targets in edges.items():
        for b in targets:
            if scc_of[a] != scc_of[b] and scc_of[b] not in dag[scc_of[a]]:
                dag[scc_of[a]].append(scc_of[b])
    scc_order = topological(sorted(range(len(sccs)), key=lambda i: min(position[n] for n in sccs[i])), dag)
    return [n for i in scc_order for n in sorted(sccs[i], key=position.get)]
