"""What an FMU says about the loop it belongs in (and what it is, `model_text`): the ``org.greyfmu`` vendor annotation of its
modelDescription.xml (FMI 2.0 ``VendorAnnotations/Tool``, FMI 3.0 ``Annotations/Annotation``).

greyfmu's build writes it (`greyfmu.wiring`); the master reads it from the FMU file alone, so
any FMU that carries it gets the checks of `cosim.plan.loopcheck` and ``cosim info``'s "what
to wire", and the master never imports greyfmu::

    <Tool name="org.greyfmu">
      <Loop sampleTime="Ts" sampleOffset="t_step">
        <Input name="r" role="setpoint"/>
        <Input name="W" role="scheduling" when="law in 0 1 2 3"/>
        <Output name="u" role="manipulated"/>
      </Loop>
    </Tool>

``sampleTime`` names the parameter holding the sample time of an FMU that acts at sample
instants only (``sampleOffset``: the parameter holding the first instant, else the
experiment's start); each ``Input`` must be connected (when its condition holds: ``PARAMETER
in V1 V2 ...`` or ``PARAMETER >= N``); an ``Output`` with role ``manipulated`` drives the plant.

There is no fallback for FMUs without the annotation (third-party ones): FMI 2.0 has no
standard way to say that a parameter is a sample time or that an input must be wired, and a
guess by name (``Ts``, ``h``) or "every unconnected input" would warn on correct systems
(gemseo-fmu's ``MassSpringSubSystem1`` has parameters as inputs ``k1``, ``m1`` meant to keep
their start values), and ``--strict`` would then refuse them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import SetupError
from ..safeio import parse_xml_bytes, read_member

TOOL = "org.greyfmu"
#: ``PARAMETER in V1 V2 ...`` or ``PARAMETER >= N``
_CONDITION = re.compile(r"(?P<parameter>\w+) (?:in (?P<values>-?\d+(?: -?\d+)*)|>= (?P<minimum>-?\d+))")


@dataclass(frozen=True)
class LoopPort:
    """A port the annotation names: ``causality`` input (must be connected when ``when`` holds,
    '' always) or output; ``role`` setpoint, measurement, scheduling, process or manipulated."""
    name: str
    causality: str
    role: str
    when: str = ""

    def required(self, value_of) -> bool:
        """Whether this input must be connected, ``value_of(parameter)`` giving a parameter's value
        (a condition that cannot be read is taken as holding: better a warning too many)."""
        if self.causality != "input":
            return False
        match = _CONDITION.fullmatch(self.when) if self.when else None
        if match is None:
            return True
        try:
            value = float(value_of(match["parameter"]))
        except (TypeError, ValueError, KeyError):
            return True
        if match["values"] is not None:
            return value in {float(v) for v in match["values"].split()}
        return value >= float(match["minimum"])


@dataclass(frozen=True)
class LoopAnnotation:
    """The annotation's facts: the sample-time and sample-offset parameters (None: not sampled,
    samples from the start) and the ports."""
    sample_time: str | None
    sample_offset: str | None
    ports: tuple[LoopPort, ...]


_cache: dict[tuple[Path, float], tuple[LoopAnnotation | None, str]] = {}


def _read(fmu: Path) -> tuple[LoopAnnotation | None, str]:
    """The annotation and the ``description`` attribute of ``fmu``'s model description, read once per file version."""
    key = (fmu, fmu.stat().st_mtime)
    if key not in _cache:
        if fmu.is_dir():
            data = (fmu / "modelDescription.xml").read_bytes()
        else:
            data = read_member(fmu, "modelDescription.xml", str(fmu), "modelDescription.xml")
        root = parse_xml_bytes(data, f"{fmu.name}/modelDescription.xml").getroot()
        _cache[key] = (_parse(root, fmu), root.get("description", ""))
    return _cache[key]


def loop_annotation(fmu: Path) -> LoopAnnotation | None:
    """The ``org.greyfmu`` annotation of the FMU file (or extracted folder) ``fmu``; None without one."""
    return _read(fmu)[0]


def model_text(fmu: Path) -> str:
    """The model description's ``description`` attribute ('' without one), for ``cosim info X.fmu``."""
    return _read(fmu)[1]


def _parse(root, fmu: Path) -> LoopAnnotation | None:
    loop = root.find(f"VendorAnnotations/Tool[@name='{TOOL}']/Loop")
    if loop is None:
        loop = root.find(f"Annotations/Annotation[@type='{TOOL}']/Loop")
    if loop is None:
        return None
    ports = []
    for node in loop:
        if node.tag not in ("Input", "Output"):
            continue
        when = node.get("when", "")
        if when and _CONDITION.fullmatch(when) is None:
            raise SetupError(f"the {TOOL} annotation's condition '{when}' is not 'PARAMETER in V1 V2 ...' or "
                             "'PARAMETER >= N'.", file=str(fmu), element=f"Loop/{node.tag} (line {node.sourceline})",
                             variable=node.get("name"))
        ports.append(LoopPort(node.get("name", ""), node.tag.lower(), node.get("role", ""), when))
    return LoopAnnotation(loop.get("sampleTime"), loop.get("sampleOffset"), tuple(ports))
