"""The FMU catalogue: every FMU of ``fmus/`` with what it is, its inputs and outputs with units,
every parameter with unit, default and range, its sample time and what to wire (build side;
``greyfmu info``, ``greyfmu catalogue``, docs/catalogue.md).  An FMU's FMI 3.0 build
(``<Name>3``, `greyfmu.fmi3`) has the same variables: the catalogue's entry stands for both, and
``greyfmu info PID3`` describes the FMI 3.0 one.

One source with the FMU's own ``documentation/index.html``: `declared_description` makes the
model description from the slave's declarations as ``greyfmu build`` writes it (pythonfmu's
``to_xml`` of an instance, then the build's output dependencies, unit definitions and the
``org.greyfmu`` annotation of `greyfmu.wiring`) without building the FMU, and both pages read it
with `greyfmu.documentation.variables` and `greyfmu.documentation.loop_text`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from xml.etree import ElementTree

from greyfmu.build import FMU_SOURCES, _declare_output_dependencies, _declare_units, fmi2_name, fmu_names, slave_class
from greyfmu.fmi3 import fmi3_name, model_description3
from greyfmu.documentation import VariableInfo, loop_text, variables
from greyfmu.names import aliases
from greyfmu.wiring import LoopFacts, annotate, loop_facts

GROUPS = ("Controllers", "Estimators and identifiers", "Plants and blocks", "Sources")
"""The catalogue's sections, in order: the controllers first."""


@dataclass(frozen=True)
class Entry:
    """One FMU as the catalogue shows it."""
    name: str
    fmi_version: str
    description: str
    experiment: dict[str, str]
    variables: tuple[VariableInfo, ...]
    loop: LoopFacts | None
    wiring: str
    """`greyfmu.documentation.loop_text`: the sample time and what to wire, in sentences."""

    @property
    def group(self) -> str:
        """Controllers drive a plant (a ``manipulated`` output); estimators read measurements; sources have no input."""
        roles = {port.role for port in self.loop.ports} if self.loop else set()
        if "manipulated" in roles:
            return GROUPS[0]
        if "measurement" in roles:
            return GROUPS[1]
        return GROUPS[3] if not self.of("input") else GROUPS[2]

    def of(self, causality: str) -> tuple[VariableInfo, ...]:
        return tuple(variable for variable in self.variables if variable.causality == causality)

    @property
    def summary(self) -> str:
        """The description's first sentence, cut at a word near 110 characters."""
        first = re.split(r"(?<=[.;:])\s(?=[A-Z])", self.description, maxsplit=1)[0].rstrip(".;:")
        return first if len(first) <= 110 else first[:107].rsplit(" ", 1)[0] + " …"


def declared_description(name: str) -> ElementTree.Element:
    """The model description of FMU ``name`` as ``greyfmu build`` writes it, before the drop-in
    step (no GUID of ours, version or licence), from the slave's declarations alone; an FMI 3.0
    name (``PID3``) gets its sibling's description made FMI 3.0 by `greyfmu.fmi3.model_description3`."""
    sibling = fmi2_name(name)
    model = sibling or name
    cls = slave_class(FMU_SOURCES / f"{model}.py")
    instance = cls(instance_name="greyfmu-catalogue", resources=str(FMU_SOURCES))
    root = instance.to_xml()
    _declare_output_dependencies(root, model, cls.output_dependencies)
    _declare_units(root, model)
    if sibling:
        root = model_description3(root, instance.choices)
    annotate(root, cls)
    return root


def entry(root: ElementTree.Element) -> Entry:
    """The catalogue entry of a model description (ours, declared or built; FMI 2.0 or 3.0)."""
    experiment = root.find("DefaultExperiment")
    return Entry(root.get("modelName"), root.get("fmiVersion"), root.get("description", ""),
                 dict(experiment.attrib) if experiment is not None else {}, tuple(variables(root)),
                 loop_facts(root), loop_text(root))


def all_names() -> list[str]:
    """Every FMU that ``greyfmu build`` can build: the FMI 2.0 set, then the FMI 3.0 builds."""
    return fmu_names() + [fmi3_name(name) for name in fmu_names()]


def entries(names: list[str] | None = None) -> list[Entry]:
    """The entries of ``names`` (default: every FMI 2.0 FMU, each standing for its FMI 3.0 sibling
    too: the same variables, `sibling`), grouped as `GROUPS`, by name within a group."""
    found = [entry(declared_description(name)) for name in (names or fmu_names())]
    return sorted(found, key=lambda e: (GROUPS.index(e.group), e.name))


def sibling(entry: Entry) -> str:
    """The FMI 3.0 build of an FMI 2.0 entry's FMU (``PID`` -> ``PID3``), '' for an FMI 3.0 entry."""
    return fmi3_name(entry.name) if entry.fmi_version.startswith("2") else ""


def _ports(entry: Entry) -> str:
    def port(variable: VariableInfo) -> str:
        return variable.name + (f" [{variable.unit}]" if variable.unit and variable.unit != "as wired" else "")
    inputs = ", ".join(port(v) for v in entry.of("input")) or "—"
    return f"{inputs} → {', '.join(port(v) for v in entry.of('output'))}"


def _experiment(entry: Entry) -> str:
    e = entry.experiment
    parts = [f"{e.get('startTime', '0')}..{e['stopTime']} s" if "stopTime" in e else "",
             f"step {e['stepSize']} s" if "stepSize" in e else ""]
    return ", ".join(part for part in parts if part) or "none declared"


def text(entry: Entry) -> str:
    """``greyfmu info NAME``: the entry as plain text for a terminal."""
    lines = [f"{entry.name} (FMI {entry.fmi_version} Co-Simulation; {entry.group.lower()})", "",
             entry.description, "", f"default experiment: {_experiment(entry)}", *entry.wiring.splitlines(),
             *([f"also as FMI 3.0: {sibling(entry)}.fmu, the same variables (`greyfmu info {sibling(entry)}`)"]
               if sibling(entry) else []), ""]
    for causality, title in (("input", "inputs"), ("output", "outputs"), ("parameter", "parameters")):
        rows = entry.of(causality)
        if not rows:
            continue
        table = [("name", "unit", "start" if causality != "parameter" else "default", "range", "description")]
        table += [(v.name, v.unit, v.start, v.range, v.description) for v in rows]
        widths = [max(len(row[i]) for row in table) for i in range(4)]
        lines.append(f"{title}:")
        lines += ["  " + "  ".join(cell.ljust(width) for cell, width in zip(row, widths)) + "  " + row[4]
                  for row in table]
    return "\n".join(line.rstrip() for line in lines)


def summary_text(found: list[Entry]) -> str:
    """``greyfmu info``: one line per FMU, by group."""
    lines = []
    width = max(len(e.name) for e in found)
    for group in GROUPS:
        members = [e for e in found if e.group == group]
        if members:
            lines += [f"{group}:"] + [f"  {e.name:{width}}  {_ports(e)}" for e in members] + [""]
    alias = aliases(e.name for e in found)
    accepted = "Also accepted: " + ", ".join(f"{a} (= {n})" for a, n in sorted(alias.items())) + ". " if alias else ""
    lines.append(accepted + "Each also as FMI 3.0, <Name>3 (PID3). `greyfmu info NAME` describes one; "
                 "`cosim info X.fmu` any FMU file.")
    return "\n".join(lines)


def _cell(value: str) -> str:
    return value.replace("|", "\\|").replace("\n", " ")


def markdown(found: list[Entry]) -> str:
    """docs/catalogue.md: an index table, then one section per FMU."""
    out = ["# FMU catalogue", "",
           "Every FMU `greyfmu build` makes, generated from the slaves' declarations in `fmus/` by "
           "`greyfmu catalogue -o docs/catalogue.md` (the FMU's own `documentation/index.html` shows the same; "
           "`greyfmu info NAME` prints one entry, `cosim info X.fmu` any FMU file, ours or not). "
           "Each is built as FMI 2.0 Co-Simulation `<Name>.fmu` and, from the same slave, as FMI 3.0 "
           "`<Name>3.fmu` (`greyfmu build PID3`, `greyfmu build --fmi 3`): the same variables, value references and "
           "defaults (Real as Float64, Integer as Int32, a mode parameter as an Enumeration, plus the independent "
           "variable `time`), so one section describes both. "
           "A Real whose unit reads *as wired* declares none: it takes the unit of the signals connected to it. "
           "`GreyPredictivePI` is accepted for `GrayPredictivePI` (the thesis's spelling, kept as the FMU's "
           "name so its GUID and every scenario naming it stay valid).", ""]
    for group in GROUPS:
        members = [e for e in found if e.group == group]
        if not members:
            continue
        out += [f"## {group}", "", "| FMU | inputs → outputs | sample time | what it is |", "|---|---|---|---|"]
        for e in members:
            ts = e.loop.sample_time if e.loop and e.loop.sample_time else "—"
            default = next((v.start for v in e.variables if v.name == ts), "")
            also = f" / `{sibling(e)}`" if sibling(e) else ""
            out.append(f"| [`{e.name}`](#{e.name.lower()}){also} | {_cell(_ports(e))} | "
                       f"{ts + f' = {default} s' if default else ts} | {_cell(e.summary)} |")
        out.append("")
    for e in found:
        also = f" (`{e.name}.fmu`; FMI 3.0: `{sibling(e)}.fmu`)" if sibling(e) else ""
        out += [f"## {e.name}", "", f"FMI {e.fmi_version} Co-Simulation{also}, {e.group.lower()}; default experiment "
                f"{_experiment(e)}.", "", _cell(e.description), "", *(f"- {line}" for line in e.wiring.splitlines()), ""]
        for causality, title, columns in (("input", "Inputs", ("unit", "start")), ("output", "Outputs", ("unit",)),
                                          ("parameter", "Parameters", ("unit", "default", "range"))):
            rows = e.of(causality)
            if not rows:
                continue
            out += [f"**{title}**", "", "| name | " + " | ".join(columns) + " | description |",
                    "|---" * (len(columns) + 2) + "|"]
            for v in rows:
                values = {"unit": v.unit, "start": v.start, "default": v.start, "range": v.range}
                out.append(f"| `{v.name}` | " + " | ".join(_cell(values[c]) for c in columns) + f" | {_cell(v.description)} |")
            out.append("")
    return "\n".join(out).rstrip() + "\n"
