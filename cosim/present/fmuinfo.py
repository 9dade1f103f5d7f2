"""``cosim info X.fmu``: what any FMU offers, from its model description alone (ours or another
tool's): what it is, the default experiment, its inputs, outputs and parameters with unit, start
(default), range and description, and, where it carries the ``org.greyfmu`` annotation
(`cosim.read.annotations`), its sample time and what to wire.
"""
from __future__ import annotations

from ..model.fmu import FMUDescription, Variable, unit_of
from ..read.annotations import loop_annotation

#: the causalities listed, in order, with their headings
SECTIONS = (("input", "inputs"), ("output", "outputs"), ("parameter", "parameters"),
            ("calculatedParameter", "calculated parameters"), ("structuralParameter", "structural parameters"))


def _range(v: Variable) -> str:
    if v.min is not None and v.max is not None:
        return f"{v.min}..{v.max}"
    return f">= {v.min}" if v.min is not None else f"<= {v.max}" if v.max is not None else ""


def _type(v: Variable) -> str:
    return v.type + (f"[{']['.join(str(d) for d in v.dimensions)}]" if v.dimensions else "")


def _description(v: Variable) -> str:
    """The variable's description, an Enumeration's items after it."""
    items = v.declared_type.items if v.declared_type is not None else ()
    return " ".join(filter(None, [v.description or "", "(" + ", ".join(f"{value} = {name}" for name, value in items)
                                  + ")" if items else ""]))


def _table(rows: list[tuple[str, ...]]) -> list[str]:
    """Columns padded to their widest cell, the last (the description) left as it is."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]) - 1)]
    return ["  " + "  ".join(cell.ljust(width) for cell, width in zip(row, widths)) + "  " + row[-1] for row in rows]


def fmu_lines(desc: FMUDescription, description: str | None = None) -> list[str]:
    """The lines ``cosim info X.fmu`` prints (``description``: the model description's own, if known)."""
    lines = [f"{desc.path.name}: {desc.model_identifier}, FMI {desc.fmi_version} {desc.kind} "
             f"({desc.generation_tool or 'generation tool not given'}), GUID {desc.guid}"]
    if description:
        lines += ["", description, ""]
    e = desc.default_experiment
    if e is not None:
        parts = [f"start {e.start_time}" if e.start_time else "", f"stop {e.stop_time}" if e.stop_time else "",
                 f"step {e.step_size}" if e.step_size else "", f"tolerance {e.tolerance}" if e.tolerance else ""]
        lines.append("default experiment: " + (", ".join(p for p in parts if p) or "empty"))
    else:
        lines.append("default experiment: none")
    facts = loop_annotation(desc.path)
    if facts is not None:
        if facts.sample_time and facts.sample_time in desc.variables:
            ts = desc.variables[facts.sample_time]
            lines.append(f"sampled every {facts.sample_time} (default {ts.start} s); use a master step that divides it")
        wire = [f"{p.name} ({p.role}{', when ' + p.when if p.when else ''})" for p in facts.ports if p.causality == "input"]
        if wire:
            lines.append("connect: " + ", ".join(wire))
        drives = [p.name for p in facts.ports if p.causality == "output"]
        if drives:
            lines.append("drives the plant: " + ", ".join(drives))
    for causality, heading in SECTIONS:
        found = [v for v in desc.variables.values() if v.causality == causality]
        if not found:
            continue
        start = "default" if "arameter" in causality else "start"
        rows = [("name", "type", "unit", start, "range", "description")]
        rows += [(v.name, _type(v), unit_of(v) or "", v.start or "", _range(v), _description(v)) for v in found]
        lines += [f"{heading} ({len(found)}):", *_table(rows)]
    return [line.rstrip() for line in lines]
