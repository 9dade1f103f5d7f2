"""``documentation/index.html`` of an FMU, generated from its model description (build side).

One page per FMU: what it is (the model description's ``description``: the paper, its
equations and the defaults' source), the default experiment, its sample time and what to
wire (the ``org.greyfmu`` annotation, `greyfmu.wiring`), every variable with causality,
variability, type, unit ("as wired" for a Real declared without one), start, min, max and
description, the unit definitions, what the target needs
(Python, modules, how the loader finds them) and the licences shipped with it.

`variables` and `loop_text` read any FMI 2.0 or 3.0 model description: the catalogue
(`greyfmu.catalogue`, ``greyfmu info``, docs/catalogue.md) shows the same facts from the same
declarations.
"""

from __future__ import annotations

from dataclasses import dataclass
from html import escape
from xml.etree import ElementTree

from greyfmu.wiring import LoopFacts, loop_facts

TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
AS_WIRED = "as wired"
"""The unit column of a Real variable that declares none (see fmus/_slave.py's docstring)."""
PYTHON_ORDER = (
    "the interpreter named by the environment variable <code>GREYFMU_PYTHON</code> (if set, no other is tried);",
    "the interpreter that built the FMU (<code>resources/greyfmu_build_python.txt</code>), if it exists on this machine;",
    "<code>python3</code> on <code>PATH</code>.",
)


def index_html(root: ElementTree.Element, requirements: tuple[str, ...], loaders: tuple[str, ...]) -> str:
    """The page of the FMU whose model description is ``root``; ``loaders``: the platform
    folders whose binary is greyfmu's loader (the others hold pythonfmu's library)."""
    model = escape(root.get("modelName"))
    experiment = root.find("DefaultExperiment")
    experiment_text = ", ".join(f"{key} = {escape(value)} s" if key != "tolerance" else f"{key} = {escape(value)}"
                                for key, value in (experiment.attrib.items() if experiment is not None else []))
    fmi3 = root.get("fmiVersion") == "3.0"
    rows = "\n".join(_variable_row(variable) for variable in variables(root))
    units = "\n".join(
        f"<tr><td>{escape(unit.get('name'))}</td><td>{escape(_base_unit(unit))}</td></tr>"
        for unit in root.iter("Unit")
    )
    modules = ", ".join(f"<code>{escape(name)}</code>" for name in requirements)
    order = "".join(f"<li>{step}</li>" for step in PYTHON_ORDER)
    linux_folder, windows_folder = ("x86_64-linux", "x86_64-windows") if fmi3 else ("linux64", "win64")
    windows = WINDOWS_LOADER if windows_folder in loaders else WINDOWS_PYTHONFMU
    linux = LINUX_LOADER if linux_folder in loaders else LINUX_PYTHONFMU
    pythonfmu = "pythonfmu3" if fmi3 else "pythonfmu"
    instantiate = "fmi3InstantiateCoSimulation" if fmi3 else "fmi2Instantiate"
    token = f"instantiation token <code>{escape(root.get('instantiationToken', ''))}</code>" if fmi3 else \
        f"GUID <code>{escape(root.get('guid', ''))}</code>"
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{model} — greyfmu FMU</title>
<style>body{{font-family:sans-serif;max-width:70em;margin:2em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #999;padding:0.2em 0.5em;text-align:left;vertical-align:top}}</style></head>
<body>
<h1>{model}</h1>
<p>FMI {escape(root.get("fmiVersion", ""))} Co-Simulation FMU, greyfmu {escape(root.get("version", ""))}, {token}.</p>
<h2>What it is</h2>
<p>{escape(root.get("description", ""))}</p>
<h2>Default experiment</h2>
<p>{experiment_text or "none declared"}</p>
<h2>Sample time and what to wire</h2>
{escape(loop_text(root)).replace(chr(10), "<br>")}
<h2>Variables</h2>
<table>
<tr><th>name</th><th>causality</th><th>variability</th><th>type</th><th>unit</th><th>start</th><th>min</th><th>max</th>
<th>description</th></tr>
{rows}
</table>
<p>A Real variable whose unit reads <em>as wired</em> has none declared: it takes the unit of the
signals connected to it (a gain: the output's per the input's), so that an importer that converts
units neither refuses nor rescales a connection from, say, a kgf/cm2 or % signal.</p>
<h2>Units</h2>
<table><tr><th>unit</th><th>in SI base units</th></tr>
{units}
</table>
<h2>What the target needs</h2>
<p>A 64-bit Linux or Windows host and a CPython 3.10 or newer with {modules} installed; the FMU embeds
its own Python code (greyfmu, the slave, pythonfmu's run-time modules).</p>
{linux.format(order=order, modules=modules, folder=linux_folder, instantiate=instantiate, pythonfmu=pythonfmu)}
{windows.format(modules=modules, folder=windows_folder, pythonfmu=pythonfmu)}
<h2>Licences</h2>
<p>{escape(root.get("license", ""))}. {escape(root.get("copyright", ""))}. The notices are in
<code>documentation/licenses/</code>.</p>
</body>
</html>
"""


LINUX_LOADER = """<p>On Linux (<code>binaries/{folder}</code>) the binary is greyfmu's loader. In a host that already
runs Python (fmpy, cosim) it uses that Python. Otherwise it takes the first usable one of</p>
<ol>{order}</ol>
<p>A usable Python is 3.10 or newer, has a shared libpython (<code>libpython3.X.so</code>) and imports
{modules}; the loader starts it inside the host with that interpreter's <code>sys.path</code>
(virtual environments included). If none is usable, <code>{instantiate}</code> logs one message
naming what is missing and how to fix it and returns NULL.</p>"""
LINUX_PYTHONFMU = """<p>On Linux the binary is {pythonfmu}'s library (this FMU was built without a C compiler): it runs
only in a host that already runs a Python 3.10+ with {modules} (fmpy, cosim).</p>"""
WINDOWS_LOADER = """<p>On Windows (<code>binaries/{folder}</code>) the binary is the same loader: it takes
<code>GREYFMU_PYTHON</code> (the full path of <code>python.exe</code>), else <code>python.exe</code> on
<code>PATH</code>, of a 64-bit CPython 3.10+ with {modules} installed, and says what is missing if
that fails.</p>"""
WINDOWS_PYTHONFMU = """<p>On Windows the binary is {pythonfmu}'s library (this FMU was built without mingw-w64): it needs
<code>python3.dll</code> of a 64-bit CPython 3.10+ (python.org installer) on <code>PATH</code>, with
{modules} installed into that Python.</p>"""


@dataclass(frozen=True)
class VariableInfo:
    """One variable of a model description (FMI 2.0 ScalarVariable or FMI 3.0 variable element) as
    the documentation shows it: every attribute as text, '' where absent; ``unit`` is `AS_WIRED`
    for a Real/Float64 that declares none."""
    name: str
    causality: str
    variability: str
    type: str
    unit: str
    start: str
    min: str
    max: str
    description: str

    @property
    def range(self) -> str:
        """``min..max``, ``>= min``, ``<= max`` or ''."""
        if self.min and self.max:
            return f"{self.min}..{self.max}"
        return f">= {self.min}" if self.min else f"<= {self.max}" if self.max else ""


def variables(root: ElementTree.Element) -> list[VariableInfo]:
    """The variables of an FMI 2.0 or 3.0 model description, in its order."""
    found = []
    for node in root.find("ModelVariables"):
        if node.tag == "ScalarVariable":  # FMI 2.0: the type is a child element
            kind = next(child for child in node if child.tag in TYPES)
            type_name, attributes = kind.tag, kind
        else:  # FMI 3.0: the element is the type
            type_name, attributes = node.tag, node
        declared = attributes.get("declaredType")
        real = type_name in ("Real", "Float64", "Float32")
        found.append(VariableInfo(
            name=node.get("name"), causality=node.get("causality", "local"),
            variability=node.get("variability", "continuous" if real or node.tag == "ScalarVariable" else "discrete"),
            type=type_name + (f" ({declared})" if declared else ""),
            unit=attributes.get("unit", AS_WIRED if real and node.get("causality") != "independent" else ""),
            start=attributes.get("start", ""),
            min=attributes.get("min", ""), max=attributes.get("max", ""), description=node.get("description", "")))
    return found


def loop_text(root: ElementTree.Element) -> str:
    """What the ``org.greyfmu`` annotation (`greyfmu.wiring`) says, in sentences: the sample time
    with its default, the inputs to connect, the output that drives the plant."""
    facts: LoopFacts | None = loop_facts(root)
    if facts is None:
        return "Not sampled: it acts at every communication step. No input must be connected."
    starts = {variable.name: variable for variable in variables(root)}
    lines = []
    if facts.sample_time is not None:
        default = starts[facts.sample_time].start
        offset = (f", from the time in {facts.sample_offset} (default {starts[facts.sample_offset].start} s)"
                  if facts.sample_offset else "")
        lines.append(f"Sampled every {facts.sample_time} (default {default} s){offset}, output held between samples: "
                     f"a master step that divides {facts.sample_time} keeps the loop the one designed "
                     "(cosim warns otherwise).")
    required = [f"{port.name} ({port.role}{', when ' + port.when if port.when else ''})"
                for port in facts.required_inputs()]
    driving = [port.name for port in facts.ports if port.causality == "output"]
    if required:
        lines.append("Connect " + ", ".join(required) + ": an input left unconnected keeps its start value "
                     "(cosim warns).")
    if driving:
        lines.append("Wire " + ", ".join(driving) + " to the plant's manipulated input.")
    return "\n".join(lines)


def _variable_row(variable: VariableInfo) -> str:
    cells = [variable.name, variable.causality, variable.variability, variable.type, variable.unit, variable.start,
             variable.min, variable.max, variable.description]
    return "<tr>" + "".join(f"<td>{escape(cell)}</td>" for cell in cells) + "</tr>"


def _base_unit(unit: ElementTree.Element) -> str:
    base = unit.find("BaseUnit")
    if base is None:
        return ""
    factor = base.get("factor", "1")
    offset = base.get("offset")
    exponents = " ".join(f"{name}^{value}" if value != "1" else name
                         for name, value in base.attrib.items() if name not in ("factor", "offset"))
    return f"{factor} {exponents or '(dimensionless)'}" + (f" + {offset}" if offset else "")
