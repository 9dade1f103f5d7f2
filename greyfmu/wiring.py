"""What to wire and how an FMU samples: the ``org.greyfmu`` annotation of modelDescription.xml (build side).

A slave declares two class attributes (read here with defaults, so a slave without them is
a plain FMU):

``sample_time``
    the name of the parameter holding the FMU's sample time, for an FMU that acts only at
    sample instants t_s + k·Ts (``SampleClock``); ``sample_offset`` names the parameter
    holding t_s when it is not the experiment's start (`GM3t1Identifier`: ``t_step``).
``wiring``
    port name -> its role in a loop: ``setpoint``, ``measurement``, ``scheduling`` or
    ``process`` for inputs the FMU's law reads (each must be connected: left at its start
    value the loop is not the one the paper closes), ``manipulated`` for an output that
    drives the plant.  ``"ROLE if PARAMETER in V1 V2"`` or ``"ROLE if PARAMETER >= N"``
    makes an input required only for those parameter values (the gain-scheduled PID's ``W``
    for laws 0-3, the digital PI's ``r2`` when ``m >= 2``).

`annotate` writes them into the model description as one vendor annotation, which the master
reads from the FMU alone (cosim never imports greyfmu)::

    <VendorAnnotations>                       (FMI 3.0: <Annotations><Annotation type="org.greyfmu">)
      <Tool name="org.greyfmu">
        <Loop sampleTime="Ts">
          <Input name="r" role="setpoint"/>
          <Input name="W" role="scheduling" when="law in 0 1 2 3"/>
          <Output name="u" role="manipulated"/>
        </Loop>
      </Tool>
    </VendorAnnotations>

FMI 2.0 §2.2.6 allows any XML inside a ``Tool`` element, and a tool ignores the ones it does
not know.  The GUID is a hash of the model description (`greyfmu.dropin.stable_guid`), so
adding the annotation changed every FMU's GUID once (issue 45); it is stable again after.
`loop_facts` reads an annotation back (the catalogue and ``documentation/index.html``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from xml.etree import ElementTree

TOOL = "org.greyfmu"
INPUT_ROLES = ("setpoint", "measurement", "scheduling", "process")
"""Roles of inputs the FMU's law reads: each must be connected (under its condition)."""
OUTPUT_ROLES = ("manipulated",)
"""Roles of outputs: what drives the plant."""
CONDITION = re.compile(r"(?P<parameter>\w+) (?:in (?P<values>-?\d+(?: -?\d+)*)|>= (?P<minimum>-?\d+))")
"""``PARAMETER in V1 V2 ...`` or ``PARAMETER >= N`` (integer parameters: modes and counts)."""


class WiringError(ValueError):
    """A slave's ``sample_time``/``wiring`` declaration names no such variable or is malformed."""


@dataclass(frozen=True)
class Port:
    """A port with a role in the loop; ``when``: the condition under which an input is required ('' always)."""
    name: str
    causality: str
    role: str
    when: str = ""


@dataclass(frozen=True)
class LoopFacts:
    """What the ``org.greyfmu`` annotation says: the sample-time parameter (None: not sampled),
    the sample-offset parameter (None: samples from the experiment's start) and the loop's ports."""
    sample_time: str | None
    sample_offset: str | None
    ports: tuple[Port, ...]

    def required_inputs(self) -> tuple[Port, ...]:
        return tuple(port for port in self.ports if port.causality == "input")


def declared_facts(slave_class: type) -> LoopFacts | None:
    """The slave class's ``sample_time``, ``sample_offset`` and ``wiring`` as `LoopFacts` (None: it declares none)."""
    sample_time = getattr(slave_class, "sample_time", None)
    wiring: dict[str, str] = getattr(slave_class, "wiring", {})
    if sample_time is None and not wiring:
        return None
    ports = []
    for name, text in wiring.items():
        role, _, when = text.partition(" if ")
        causality = "input" if role in INPUT_ROLES else "output" if role in OUTPUT_ROLES else None
        if causality is None:
            raise WiringError(f"{slave_class.__name__}.wiring[{name!r}]: role {role!r} is none of "
                              f"{', '.join(INPUT_ROLES + OUTPUT_ROLES)}")
        ports.append(Port(name, causality, role, when.strip()))
    return LoopFacts(sample_time, getattr(slave_class, "sample_offset", None), tuple(ports))


def annotate(root: ElementTree.Element, slave_class: type) -> None:
    """Write the slave class's `declared_facts` into the model description ``root`` (FMI 2.0 or
    3.0) as the ``org.greyfmu`` annotation, after checking that every name is a variable of the
    right causality and every condition names an Integer parameter (WiringError otherwise)."""
    facts = declared_facts(slave_class)
    if facts is None:
        return
    fmi3 = root.get("fmiVersion", "").startswith("3")
    variables = {node.get("name"): node for node in root.find("ModelVariables") if node.get("name")}
    model = root.get("modelName")

    def check(name: str | None, causality: str, what: str) -> None:
        if name is not None and (name not in variables or variables[name].get("causality") != causality):
            raise WiringError(f"{model}: {what} names {name!r}, which is not one of the FMU's {causality}s")

    check(facts.sample_time, "parameter", "sample_time")
    check(facts.sample_offset, "parameter", "sample_offset")
    loop = ElementTree.Element("Loop")
    if facts.sample_time is not None:
        loop.set("sampleTime", facts.sample_time)
    if facts.sample_offset is not None:
        loop.set("sampleOffset", facts.sample_offset)
    for port in facts.ports:
        check(port.name, port.causality, f"wiring[{port.name!r}]")
        if port.when:
            match = CONDITION.fullmatch(port.when)
            if match is None:
                raise WiringError(f"{model}: wiring[{port.name!r}]: condition {port.when!r} is not "
                                  "'PARAMETER in V1 V2 ...' or 'PARAMETER >= N'")
            check(match["parameter"], "parameter", f"the condition of wiring[{port.name!r}]")
        ElementTree.SubElement(loop, "Input" if port.causality == "input" else "Output",
                               {"name": port.name, "role": port.role, **({"when": port.when} if port.when else {})})
    if fmi3:
        container = _container(root, "Annotations")
        ElementTree.SubElement(container, "Annotation", type=TOOL).append(loop)
    else:
        container = _container(root, "VendorAnnotations")
        ElementTree.SubElement(container, "Tool", name=TOOL).append(loop)


def _container(root: ElementTree.Element, tag: str) -> ElementTree.Element:
    """The model description's annotations element, made where the schema puts it if missing: FMI
    2.0's VendorAnnotations right before ModelVariables (§2.2.1), FMI 3.0's Annotations last (§2.4.1)."""
    found = root.find(tag)
    if found is None:
        found = ElementTree.Element(tag)
        if tag == "Annotations":
            root.append(found)
        else:
            root.insert(list(root).index(root.find("ModelVariables")), found)
    return found


def loop_facts(root: ElementTree.Element) -> LoopFacts | None:
    """The ``org.greyfmu`` annotation of a model description (FMI 2.0 or 3.0), None without one."""
    loop = root.find(f"VendorAnnotations/Tool[@name='{TOOL}']/Loop")
    if loop is None:
        loop = root.find(f"Annotations/Annotation[@type='{TOOL}']/Loop")
    if loop is None:
        return None
    ports = tuple(Port(node.get("name"), "input" if node.tag == "Input" else "output", node.get("role"),
                       node.get("when", "")) for node in loop if node.tag in ("Input", "Output"))
    return LoopFacts(loop.get("sampleTime"), loop.get("sampleOffset"), ports)
