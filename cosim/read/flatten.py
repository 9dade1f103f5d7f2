"""Flatten a hierarchy of SSP systems into one level of components and direct connections.

SSP 1.0 lets an ``ssd:System`` hold other systems in its ``ssd:Elements`` and
declare its own ``ssd:Connectors``.  A connection whose ``startElement`` or
``endElement`` is omitted names a connector of the enclosing system
(SystemStructureDescription.xsd, Connection).  The direction of the data flow
follows from the connector kinds (same documentation): between two elements of
a system it goes from an output to an input; between an element and the
enclosing system's own connector the kinds match, and an ``input`` of the
system feeds the element while an element's ``output`` feeds the system's
``output``.

The master runs a flat list of components, so this module resolves every chain
output → system connector → … → system connector → input into one direct
connection between the two components, at any depth, keeping the connections on
the way (`Hop`, with the units their system connectors declare): SSP 1.0
converts units and then applies the ``ssc:LinearTransformation`` on each
connection, so `cosim.plan.routing` composes them hop by hop into one affine map.
Names are paths relative to the root system: component ``ctrl`` of subsystem ``loop`` is ``loop.ctrl``; the root system's own
components keep their plain names, and the root system's name goes to the run
metadata, not into every column.

System connectors are handled explicitly, never dropped:

* driven by two connections: refused, naming both;
* with no driver but feeding something: it needs a value from a
  ParameterBinding (at its own system's level, named like a variable of that
  system: ``r`` on the root, ``loop.r`` from the root or ``r`` on ``loop``), which
  becomes the start value of every input or parameter it reaches (hop by hop,
  like a connection) — a constant input.  Without a value it is refused
  (`cosim.plan.parameters.bind_system_connectors`, run when all parameter sets are known);
* root ``output`` connectors are recorded under their own name as an alias of the
  component output driving them (`SystemOutput`).  One that no component output drives
  (no connection, or only undriven outputs of nested systems) is accepted, as SSP 1.0
  requires no connector to be connected (and OMSimulator and fmpy.ssp accept it): it is
  recorded as a constant, its ParameterBinding value or NaN, with a warning
  (`cosim.plan.build`); one fed by an undriven system input is refused (give the value to the
  output itself);
* unconnected connectors, and outputs of a nested system that feed nothing,
  have no effect, like an unconnected connector of a component; a value for one
  is accepted and has no effect either (an `OpenConnector` without sinks).

Signal dictionaries (SSP 1.0 SignalDictionary, SignalDictionaryReference): each entry of a
dictionary is a connector of kind ``signal`` of the system that declares it, named
``dictionary.entry``; a connection to a reference's connector is a connection to that entry of the dictionary
the reference names (looked up from the reference's system outwards), so one writer feeds any
number of readers through the same chain resolution, and two writers are refused.

ParameterBindings of a nested system name variables relative to it and are
prefixed with its path; SSP 1.0 (ParameterBindings) gives bindings at a higher
level precedence, so the flattened list puts the deepest systems first (later
bindings win in `cosim.plan.parameters`).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, replace

from ..errors import SetupError, did_you_mean
from ..model.structure import (
    Component,
    Connection,
    Connector,
    Hop,
    OpenConnector,
    ParameterValue,
    RawStructure,
    RawSystem,
    SignalDictionary,
    SignalReference,
    SystemNode,
    SystemOutput,
    SystemStructure,
)

#: Whether a connector is the sending end of a connection, by its kind, seen from the system holding
#: the connection: on one of its elements (component or subsystem), or on the system itself.
#: Calculated parameters are not supported through systems (the master does not route parameters).
_SENDS_AS_ELEMENT = {"output": True, "input": False, "parameter": False}
_SENDS_AS_OWN = {"input": True, "parameter": True, "output": False}


# A node of the connection graph: ("c", component path, connector) or ("s", system path, connector);
# the root system's path is "".
Node = tuple[str, str, str]


@dataclass
class _Edge:
    src: Node
    dst: Node
    connection: Connection


def node_name(node: Node) -> str:
    """``loop.ctrl.u`` for a component connector, ``loop.r`` (or ``r`` on the root) for a system's."""
    return f"{node[1]}.{node[2]}" if node[1] else node[2]


def flatten(raw: RawStructure) -> SystemStructure:
    """Resolve the hierarchy of ``raw`` into components and component-to-component connections."""
    file = raw.display
    walker = _Walker(file)
    hierarchy = walker.walk(raw.root, "", 0)
    parameters = [p for _, values in sorted(walker.parameters, key=lambda dp: -dp[0]) for p in values]
    resolver = _Resolver(file, walker)
    connections = walker.direct + resolver.routes()
    files, experiment = raw.files, raw.experiment
    return SystemStructure(name=raw.name, system_name=raw.root.name, ssd_file=files.ssd_file,
                           base_dir=files.base_dir, components=walker.components, connections=connections,
                           parameters=parameters, start_time=experiment.start_time,
                           stop_time=experiment.stop_time, step_size=experiment.step_size,
                           step_size_source=experiment.step_size_source, algorithm=experiment.algorithm,
                           units=raw.units, archive=files.archive, _tmp=raw._tmp,
                           hierarchy=hierarchy, system_outputs=resolver.system_outputs,
                           open_connectors=resolver.open_connectors,
                           driven_connectors={node_name(n) for n in resolver.driver})


class _Walker:
    """Collects components, direct connections and directed edges through system connectors."""

    def __init__(self, file: str):
        self.file = file
        self.components: dict[str, Component] = {}
        self.direct: list[Connection] = []
        self.edges: list[_Edge] = []
        self.system_connectors: dict[Node, Connector] = {}
        self.component_kinds: dict[Node, str] = {}
        self.parameters: list[tuple[int, list[ParameterValue]]] = []
        #: the systems enclosing the one being walked, innermost last (signal dictionary lookup)
        self.scopes: list[tuple[str, RawSystem]] = []

    def walk(self, system: RawSystem, path: str, depth: int) -> SystemNode:
        self.scopes.append((path, system))
        try:
            return self._walk(system, path, depth)
        finally:
            self.scopes.pop()

    def _walk(self, system: RawSystem, path: str, depth: int) -> SystemNode:
        prefix = f"{path}." if path else ""
        label = f"system '{path}'" if path else f"the root system '{system.name}'"
        for dictionary in system.dictionaries.values():
            for entry, conn in dictionary.entries.items():
                self.system_connectors[("s", path, f"{dictionary.name}.{entry}")] = replace(
                    conn, name=f"{dictionary.name}.{entry}")
        for ref in system.references.values():
            self._dictionary_of(ref, label)
        for name, conn in system.connectors.items():
            if conn.kind == "inout":
                raise SetupError("system connectors of kind 'inout' are not supported: SSP 1.0 gives them no "
                                 "data-flow direction; declare an input or an output.", file=self.file,
                                 element=f"ssd:Connector '{name}' of {label} (line {conn.line})", variable=name)
            self.system_connectors[("s", path, name)] = conn
        children: list[SystemNode] = []
        for name in system.elements:  # document order: it orders the results' columns and Gauss-Seidel ties
            if name in system.systems:
                children.append(self.walk(system.systems[name], prefix + name, depth + 1))
                continue
            comp, full = system.components[name], prefix + name
            if full in self.components:
                raise SetupError(f"two components flatten to the same path '{full}'.", file=self.file,
                                 element=f"ssd:Component '{name}' of {label} (line {comp.line})",
                                 hint="Rename one of them; dots in names clash with subsystem paths.")
            self.components[full] = replace(comp, name=full) if full != comp.name else comp
            for cname, conn in comp.connectors.items():
                self.component_kinds[("c", full, cname)] = conn.kind
        for c in system.connections:
            self._connection(system, path, label, c)
        self.parameters.append((depth, [replace(p, name=prefix + p.name) for p in system.parameters] if prefix
                                else list(system.parameters)))
        return SystemNode(system.name, path, system.line, tuple(system.connectors.values()),
                          tuple(prefix + n for n in system.components), tuple(children))

    def _connection(self, system: RawSystem, path: str, label: str, c: Connection) -> None:
        prefix = f"{path}." if path else ""
        where = f"ssd:Connection (line {c.line}) in {label}"
        ends = [self._end(system, path, label, element, connector, where)
                for element, connector in ((c.start_element, c.start_connector), (c.end_element, c.end_connector))]
        if all(node[0] == "c" for node, _ in ends):
            # component to component: cosim.plan.build directs and checks it against the FMUs
            self.direct.append(replace(c, start_element=prefix + c.start_element,
                                       end_element=prefix + c.end_element) if prefix else c)
            return
        (a, a_sends), (b, b_sends) = ends
        if a_sends is None and b_sends is None:
            raise SetupError(f"the direction of the connection between {node_name(a)} and {node_name(b)} cannot be "
                             "told: declare the component's connector (input or output), or give the signal "
                             "dictionary reference's connector the kind input or output.", file=self.file,
                             element=where)
        # an undirected end (component or signal dictionary reference) takes the direction the other gives it
        a_sends = (not b_sends) if a_sends is None else a_sends
        b_sends = (not a_sends) if b_sends is None else b_sends
        if a_sends == b_sends:
            role = "send" if a_sends else "receive"
            raise SetupError(f"both ends {role} ({node_name(a)} and {node_name(b)}): a connection goes from an "
                             "output of an element (or an input of the enclosing system) to an input of an "
                             "element (or an output of the enclosing system).", file=self.file, element=where)
        src, dst = (a, b) if a_sends else (b, a)
        self.edges.append(_Edge(src, dst, c))

    def _end(self, system: RawSystem, path: str, label: str, element: str | None, connector: str,
             where: str) -> tuple[Node, bool | None]:
        """The node and whether it is the sending end; None for a component connector that is not
        declared, or whose kind has no direction here: the other end decides, cosim.plan.build checks it."""
        prefix = f"{path}." if path else ""
        if element is None:
            conn = system.connectors.get(connector)
            if conn is None:
                raise SetupError(f"{label} has no connector '{connector}' (a connection without an element "
                                 "names a connector of the enclosing system).", file=self.file, element=where,
                                 variable=connector, hint=did_you_mean(connector, system.connectors))
            return ("s", path, connector), self._sends(conn, _SENDS_AS_OWN, f"{label}", where)
        if element in system.components:
            conn = system.components[element].connectors.get(connector)
            return ("c", prefix + element, connector), (_SENDS_AS_ELEMENT.get(conn.kind) if conn else None)
        if element in system.references:
            return self._signal(system.references[element], connector, label, where)
        if element in system.systems:
            sub = system.systems[element]
            conn = sub.connectors.get(connector)
            if conn is None:
                raise SetupError(f"system '{prefix + element}' has no connector '{connector}'.", file=self.file,
                                 element=where, variable=connector, hint=did_you_mean(connector, sub.connectors))
            return ("s", prefix + element, connector), self._sends(conn, _SENDS_AS_ELEMENT,
                                                                   f"system '{prefix + element}'", where)
        raise SetupError(f"unknown component '{element}' in {label}.", file=self.file, element=where,
                         hint=did_you_mean(element, [*system.components, *system.systems, *system.references]))

    def _signal(self, ref: SignalReference, connector: str, label: str, where: str) -> tuple[Node, bool | None]:
        """A connector of a signal dictionary reference: the dictionary entry it names, a node of
        the system that declares the dictionary (looked up from the reference's system outwards,
        SSP 1.0 SignalDictionaryReference).  Its kind, as a component's, says whether the reference
        reads the signal (output) or writes it (input); inout or none: the other end decides."""
        owner, dictionary = self._dictionary_of(ref, label)
        element = f"ssd:SignalDictionaryReference '{ref.name}' (line {ref.line}) in {label}"
        if connector not in dictionary.entries:
            raise SetupError(f"signal dictionary '{ref.dictionary}' (entries in {dictionary.file}) has no entry "
                             f"'{connector}'.", file=self.file,
                             element=f"{where}, {element}", variable=connector,
                             hint=did_you_mean(connector, dictionary.entries))
        conn = ref.connectors.get(connector)
        return ("s", owner, f"{ref.dictionary}.{connector}"), (_SENDS_AS_ELEMENT.get(conn.kind) if conn else None)

    def _dictionary_of(self, ref: SignalReference, label: str) -> tuple[str, SignalDictionary]:
        """The path of the system declaring the dictionary ``ref`` names, and the dictionary."""
        for path, system in reversed(self.scopes):
            if ref.dictionary in system.dictionaries:
                return path, system.dictionaries[ref.dictionary]
        raise SetupError(f"no signal dictionary '{ref.dictionary}' in this system or an enclosing one.",
                         file=self.file, element=f"ssd:SignalDictionaryReference '{ref.name}' (line {ref.line}) "
                         f"in {label}")

    def _sends(self, conn: Connector, table: dict[str, bool], owner: str, where: str) -> bool:
        if conn.kind not in table:
            raise SetupError(f"connector '{conn.name}' of {owner} has kind '{conn.kind}', which this master "
                             "cannot connect through a system (input, output, parameter are supported).",
                             file=self.file, element=where, variable=conn.name)
        return table[conn.kind]


class _Resolver:
    """Follows the edges from each component output through system connectors to the inputs."""

    def __init__(self, file: str, walker: _Walker):
        self.file = file
        self.walker = walker
        self.driver: dict[Node, _Edge] = {}  # system connectors only: graph checks component inputs
        self.fanout: dict[Node, list[_Edge]] = defaultdict(list)
        for e in walker.edges:
            if e.dst[0] == "s":
                if e.dst in self.driver:
                    other = self.driver[e.dst].connection
                    raise SetupError(f"system connector '{node_name(e.dst)}' is driven by two connections "
                                     f"(lines {other.line} and {e.connection.line}).", file=file,
                                     element=f"ssd:Connection (line {e.connection.line})",
                                     variable=node_name(e.dst))
                self.driver[e.dst] = e
            self.fanout[e.src].append(e)
        self.system_outputs: dict[str, SystemOutput] = {}
        self.open_connectors: dict[str, OpenConnector] = {}
        #: root outputs fed only by undriven outputs of nested systems (`_open`)
        self.fed_undriven: dict[str, SystemOutput] = {}

    def routes(self) -> list[Connection]:
        self._check_no_loops()
        routes: list[Connection] = []
        for src in list(self.fanout):
            if src[0] == "c":
                for e in self.fanout[src]:
                    routes += self._follow(src, e, [])
            elif src not in self.driver:
                self._open(src)
        for node, conn in self.walker.system_connectors.items():
            root_output = node[1] == "" and conn.kind == "output"
            if not root_output and node not in self.driver and node_name(node) not in self.open_connectors:
                # feeds nothing: a value for it is accepted and has no effect (OMSimulator's systems give them)
                self.open_connectors[node_name(node)] = OpenConnector(node_name(node), conn.kind, conn.line, [],
                                                                      conn.unit)
            if root_output and node not in self.driver:
                self.system_outputs[node[2]] = SystemOutput(node[2], None, None, conn.line,
                                                            undriven="no connection drives it", declared=conn)
            elif root_output and node[2] in self.fed_undriven:
                self.system_outputs[node[2]] = self.fed_undriven[node[2]]
        return routes

    def _check_no_loops(self) -> None:
        for start in self.driver:
            seen = {start}
            node = start
            while node in self.driver and self.driver[node].src[0] == "s":
                node = self.driver[node].src
                if node in seen:
                    raise SetupError(f"system connectors '{node_name(start)}' … '{node_name(node)}' feed each "
                                     "other in a loop with no component on it.", file=self.file,
                                     element=f"ssd:Connection (line {self.driver[node].connection.line})")
                seen.add(node)

    def _follow(self, origin: Node, edge: _Edge, hops: list[_Edge]) -> list[Connection]:
        """Connections from ``origin`` (a component output) through ``edge`` and what follows it:
        each with the connections on the way as its hops (`cosim.plan.routing` composes them)."""
        c = edge.connection
        hops = hops + [edge]
        dst = edge.dst
        if dst[0] == "c":
            kind = self.walker.component_kinds.get(dst)
            if kind == "parameter":
                raise SetupError(f"parameter '{node_name(dst)}' is wired to the output {node_name(origin)} "
                                 "through system connectors; parameter connections are not supported, give the "
                                 "value with a ParameterBinding.", file=self.file,
                                 element=f"ssd:Connection (line {c.line})", variable=dst[2])
            lines = ", ".join(str(h.connection.line) for h in hops)
            through = ", ".join(node_name(h.dst) for h in hops[:-1])
            return [Connection(origin[1], origin[2], dst[1], dst[2], None, False, hops[0].connection.line,
                               via=f"lines {lines} through system connector {through}", hops=self._hops(hops))]
        out: list[Connection] = []
        for nxt in self.fanout.get(dst, []):
            out += self._follow(origin, nxt, hops)
        if dst[1] == "" and self.walker.system_connectors[dst].kind == "output":
            self.system_outputs[dst[2]] = SystemOutput(dst[2], origin[1], origin[2],
                                                       self.walker.system_connectors[dst].line, self._hops(hops))
        return out

    def _hops(self, edges: list[_Edge]) -> tuple[Hop, ...]:
        """The `Hop` of each edge, with the units its system connectors declare."""
        def end(node: Node) -> tuple[str | None, str | None]:
            return (node_name(node), self.walker.system_connectors[node].unit) if node[0] == "s" else (None, None)

        out = []
        for e in edges:
            (start, start_unit), (stop, stop_unit), c = end(e.src), end(e.dst), e.connection
            out.append(Hop(c.line, start, stop, start_unit, stop_unit, c.transform, c.suppress_unit_conversion))
        return tuple(out)

    def _open(self, node: Node) -> None:
        """An undriven system connector that feeds something: list what a binding would set."""
        conn = self.walker.system_connectors[node]
        sinks: list[tuple[str, str, tuple[Hop, ...]]] = []
        stack = [(e, [e]) for e in self.fanout[node]]
        while stack:
            e, path = stack.pop()
            if e.dst[0] == "c":
                sinks.append((e.dst[1], e.dst[2], self._hops(path)))
                continue
            if e.dst[1] == "" and self.walker.system_connectors[e.dst].kind == "output":
                if conn.kind == "output":  # an undriven output of a nested system: as if unconnected
                    root = self.walker.system_connectors[e.dst]
                    self.fed_undriven[e.dst[2]] = SystemOutput(
                        e.dst[2], None, None, root.line, self._hops(path), declared=root,
                        undriven=f"it is fed only by '{node_name(node)}', which no connection drives")
                    continue
                raise SetupError(f"root output connector '{e.dst[2]}' is fed by '{node_name(node)}', which no "
                                 "component drives; only component outputs can be recorded.", file=self.file,
                                 element=f"ssd:Connection (line {e.connection.line})", variable=e.dst[2])
            stack += [(nxt, path + [nxt]) for nxt in self.fanout.get(e.dst, [])]
        if sinks:
            self.open_connectors[node_name(node)] = OpenConnector(node_name(node), conn.kind, conn.line,
                                                              sinks, conn.unit)
