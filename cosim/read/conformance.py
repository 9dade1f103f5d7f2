"""A model description against the rules of the FMI standard that fmpy checks when it reads one
(`fmpy.read_model_description(validate=True)`: the FMI schema, then
`fmpy.validation.validate_model_description`), each rule either tolerated or refused.

Exporters bend these rules every day (Simulink's FMI Kit leaves an Enumeration's variability at
FMI 2.0's default, ``continuous``; Dymola writes units it does not define), and other masters run
such FMUs: OMSimulator does not check them, ``fmpy.simulate_fmu(validate=False)`` skips them.  So
the master runs an FMU that breaks a rule it can run through, with one warning for each place
(`StandardBent`, a `cosim.errors.CosimWarning`: ``cosim --strict`` refuses instead), and refuses the FMU
when the rule is one it cannot run through.  What cannot run at all is refused before this:
a model description fmpy cannot parse (broken XML, a missing value reference, a declared type
that does not exist, a causality and variability fmpy finds no initial for) by
`cosim.read.description.describe`, an archive or library that cannot load by `cosim.read.loadable`.

The rules, fmpy's message (what `fmpy validate` prints) and the decision, argued (`RULES`):

========================  =========  =========================================================
rule                      decision   why
========================  =========  =========================================================
``schema``                tolerated  fmpy's parser read the document (else refused); what the
                                     master uses of it is checked by the rules below and by
                                     `describe` (causality values among them)
``causality``             refused    a causality outside the standard's list: the master cannot
                                     tell an input from an output (its variable would be dropped)
``unique-names``          refused    a connector, a result column, a start value name one
                                     variable: two of one name cannot be told apart
``value-references``      tolerated  two variables of one type share a value reference: read and
                                     written as one variable, as an FMI 2.0 alias is
``value-reference-types`` refused    two of different types share one: a value would be read as
                                     another type's bytes
``variability``           tolerated  a non-Real variable declared continuous (or left at FMI
                                     2.0's default): exchanged as discrete, at communication
                                     points, which is all a co-simulation master does with it
``start-missing``         tolerated  an input or exact/approx variable without a start: the master
                                     sets only the values a scenario gives; the FMU keeps its own
``combination``           tolerated  causality, variability and initial outside the standard's
                                     table: the master acts on causality alone
``calculated-start``      tolerated  initial="calculated" with a start: the start is ignored,
                                     the master never sets one on a calculated variable
``independent-start``     tolerated  the independent variable with a start: ignored (the master
                                     gives time through its FMI calls)
``unit-undefined``        tolerated  a unit not in UnitDefinitions: looked up as a unit of the
                                     scenario or the master's built-in table, else a name that
                                     converts to nothing but itself (`cosim.model.units`)
``display-unit``          tolerated  a displayUnit not defined: the master does not use display
                                     units
``independent-count``     tolerated  (FMI 3.0) not exactly one independent variable: the master
                                     never reads it
========================  =========  =========================================================

Not checked: the rules only ``fmpy validate`` applies and ``fmpy.simulate_fmu`` does not (variable
names against the structured naming convention, completeness of the ModelStructure, backslashes
in archive paths): the master reads outputs missing from the ModelStructure as depending on every
input, the conservative reading.
"""
from __future__ import annotations

import warnings
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from ..errors import CosimWarning, SetupError
from ..safeio import parse_xml_bytes, read_member

#: the causalities of FMI 2.0 §2.2.7 and FMI 3.0 §2.4.7.4
CAUSALITIES = frozenset({"parameter", "calculatedParameter", "structuralParameter", "input", "output", "local",
                         "independent"})
REAL_TYPES = frozenset({"Real", "Float32", "Float64"})

#: the legal (causality, variability, initial) triples (FMI 2.0 §2.2.7 table, FMI 3.0 §2.4.7.4), as fmpy lists them
LEGAL_COMBINATIONS = frozenset({
    ("structuralParameter", "fixed", "exact"), ("structuralParameter", "tunable", "exact"),
    ("parameter", "fixed", "exact"), ("parameter", "tunable", "exact"),
    ("calculatedParameter", "fixed", "calculated"), ("calculatedParameter", "fixed", "approx"),
    ("calculatedParameter", "tunable", "calculated"), ("calculatedParameter", "tunable", "approx"),
    ("input", "discrete", "exact"), ("input", "continuous", "exact"),
    ("output", "constant", "exact"),
    ("output", "discrete", "calculated"), ("output", "discrete", "exact"), ("output", "discrete", "approx"),
    ("output", "continuous", "calculated"), ("output", "continuous", "exact"), ("output", "continuous", "approx"),
    ("local", "constant", "exact"),
    ("local", "fixed", "calculated"), ("local", "fixed", "approx"),
    ("local", "tunable", "calculated"), ("local", "tunable", "approx"),
    ("local", "discrete", "calculated"), ("local", "discrete", "exact"), ("local", "discrete", "approx"),
    ("local", "continuous", "calculated"), ("local", "continuous", "exact"), ("local", "continuous", "approx"),
    ("independent", "continuous", None),
})


@dataclass(frozen=True)
class Rule:
    """A rule of the standard as the master applies it: ``tolerated`` (a warning, the run goes on)
    or refused; ``source`` where the standard says it; ``run_as`` what the master does instead."""
    name: str
    source: str
    tolerated: bool
    run_as: str = ""


RULES = {rule.name: rule for rule in (
    Rule("schema", "the FMI XML schema", True, "fmpy reads it; the master checks what it uses"),
    Rule("causality", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.4: causality", False),
    Rule("unique-names", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7: unique variable names", False),
    Rule("value-references", "FMI 3.0 §2.4.7: unique value references", True,
         "read and written as one variable, as FMI 2.0 aliases are"),
    Rule("value-reference-types", "FMI 3.0 §2.4.7: unique value references", False),
    Rule("variability", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.4: only Real variables are continuous", True,
         "exchanged as discrete"),
    Rule("start-missing", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.5: inputs and exact/approx variables have a start",
         True, "the master sets only the values the scenario gives"),
    Rule("combination", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.4: combinations of causality, variability and initial",
         True, "the master acts on its causality alone"),
    Rule("calculated-start", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.5: no start on initial=\"calculated\"", True,
         "the start is ignored"),
    Rule("independent-start", "FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.4: no start on the independent variable", True,
         "the start is ignored"),
    Rule("unit-undefined", "FMI 2.0 §2.2.2, FMI 3.0 §2.4.3: a unit is defined in UnitDefinitions", True,
         "looked up among the scenario's and the master's units, else converted to nothing but itself"),
    Rule("display-unit", "FMI 2.0 §2.2.2, FMI 3.0 §2.4.3: a displayUnit is defined under its unit", True,
         "the master does not use display units"),
    Rule("independent-count", "FMI 3.0 §2.4.7.4: exactly one independent variable", True,
         "the master never reads it"),
)}


class StandardBent(CosimWarning):
    """An FMU's model description breaks a rule of the standard the master tolerates."""


def warn(bends: tuple[tuple[str, str], ...]) -> None:
    """One `StandardBent` warning per place (``cosim --strict`` makes the first an error)."""
    for _, message in bends:
        warnings.warn(StandardBent(message), stacklevel=3)


def _message(fmu: str, rule: str, line: int | None, detail: str) -> str:
    """``fmu, modelDescription.xml line N: what (rule 'name': where the standard says it)``, and
    for a tolerated rule, how it is run."""
    where = f"modelDescription.xml line {line}" if line else "modelDescription.xml"
    text = f"{fmu}, {where}: {detail} (rule '{rule}': {RULES[rule].source})"
    return f"{text}; run as OMSimulator and fmpy.simulate_fmu(validate=False) run it: {RULES[rule].run_as} " \
        "(--strict refuses it)" \
        if RULES[rule].tolerated else f"{text}; the master cannot run an FMU that breaks this rule."


def check(md, path: Path, *, schemas: Path | None, file: str, where: str) -> tuple[tuple[str, str], ...]:
    """(rule, warning) of each place fmpy's parse ``md`` of ``path``'s model description breaks a
    tolerated rule; a refused rule raises `SetupError` naming the FMU, the rule and the line.
    ``schemas``: the folder of the FMI XSD files to validate the document against (fmpy's
    ``schema``), None not to (its content passed before)."""
    found: list[tuple[str, int | None, str]] = []
    if schemas is not None:
        found += [("schema", line, text) for line, text in schema_problems(path, md.fmiVersion, schemas, file, where)]
    found += _variable_rules(md)
    for rule, line, detail in found:
        if not RULES[rule].tolerated:
            raise SetupError(_message(path.name, rule, line, detail), file=file, element=where)
    return tuple((rule, _message(path.name, rule, line, detail)) for rule, line, detail in found)


def schema_problems(path: Path, fmi_version: str, schemas: Path, file: str, where: str) -> list[tuple[int, str]]:
    """(line, message) of each place the document is not valid against the FMI schema of its
    version (the XSD files in ``schemas``, fmpy's, as `fmpy.read_model_description` validates)."""
    display = f"{path.name}!modelDescription.xml"
    data = (path / "modelDescription.xml").read_bytes() if path.is_dir() else \
        read_member(path, "modelDescription.xml", file, where)
    root = parse_xml_bytes(data, display).getroot()
    major = "fmi2" if fmi_version == "2.0" else "fmi3"
    schema = _schema(schemas / major / f"{major}ModelDescription.xsd")
    if schema.validate(root):
        return []
    return [(e.line, e.message) for e in schema.error_log]


_schemas: dict[Path, etree.XMLSchema] = {}


def _schema(xsd: Path) -> etree.XMLSchema:
    if xsd not in _schemas:
        _schemas[xsd] = etree.XMLSchema(file=str(xsd))
    return _schemas[xsd]


def _variable_rules(md) -> list[tuple[str, int | None, str]]:
    """fmpy.validation.validate_model_description's rules, each found once per place."""
    found: list[tuple[str, int | None, str]] = []
    units = {u.name: {d.name for d in u.displayUnits} for u in md.unitDefinitions}
    fmi3 = md.fmiVersion.startswith("3.")
    counts = Counter(v.name for v in md.modelVariables)
    by_reference: dict[int, object] = {}
    for v in md.modelVariables:
        line, name = v.sourceline, f"variable '{v.name}'"
        if v.causality not in CAUSALITIES:
            found.append(("causality", line, f"{name} has causality=\"{v.causality}\""))
        if counts[v.name] > 1:
            found.append(("unique-names", line, f"{name} is declared {counts[v.name]} times"))
        if fmi3 and not getattr(v, "alias", None):
            other = by_reference.setdefault(v.valueReference, v)
            if other is not v:
                rule = "value-references" if other.type == v.type else "value-reference-types"
                found.append((rule, line,
                              f"{name} ({v.type}) has the value reference {v.valueReference} of variable "
                              f"'{other.name}' ({other.type}, line {other.sourceline})"))
        if v.type not in REAL_TYPES and v.variability == "continuous":
            found.append(("variability", line, f"{name} is a{'n' if v.type[0] in 'AEIOU' else ''} {v.type} with "
                                               "variability=\"continuous\""))
        if v.type != "Clock" and (v.initial in ("exact", "approx") or v.causality == "input") and v.start is None:
            found.append(("start-missing", line, f"{name} ({v.causality}, initial=\"{v.initial}\") has no start"))
        if (v.causality, v.variability, v.initial) not in LEGAL_COMBINATIONS and v.causality in CAUSALITIES:
            found.append(("combination", line, f"{name} has causality=\"{v.causality}\", variability="
                                               f"\"{v.variability}\", initial=\"{v.initial}\""))
        if v.initial == "calculated" and v.start:
            found.append(("calculated-start", line, f"{name} has initial=\"calculated\" and start=\"{v.start}\""))
        if v.causality == "independent" and v.start:
            found.append(("independent-start", line, f"{name} is the independent variable and has start="
                                                     f"\"{v.start}\""))
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        if unit is not None and unit not in units:
            found.append(("unit-undefined", line, f"{name} has the unit '{unit}', which UnitDefinitions does "
                                                  "not define"))
        for display in [getattr(v, "displayUnit", None), *(a.displayUnit for a in getattr(v, "aliases", ()))]:
            if display is not None and display not in units.get(unit, ()):
                found.append(("display-unit", line, f"{name} has the displayUnit '{display}', which unit "
                                                    f"'{unit}' does not define"))
    if fmi3:
        independent = [v.name for v in md.modelVariables if v.causality == "independent"]
        if len(independent) != 1:
            found.append(("independent-count", None, f"{len(independent)} independent variables "
                                                     f"({', '.join(independent) or 'none'})"))
    return found
