"""``documentation/index.html`` of an FMU, generated from its model description (build side).

One page per FMU: what it is (the model description's ``description``: the paper, its
equations and the defaults' source), the default experiment, every variable with causality,
variability, type, unit ("as wired" for a Real declared without one), start, min, max and
description, the unit definitions, what the target needs
(Python, modules, how the loader finds them) and the licences shipped with it.
"""

from __future__ import annotations

from html import escape
from xml.etree import ElementTree

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
    variables = list(root.find("ModelVariables")) if fmi3 else root.findall("ModelVariables/ScalarVariable")
    rows = "\n".join(_variable_row(variable, variable if fmi3 else variable[0]) for variable in variables)
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


def _variable_row(variable: ElementTree.Element, kind: ElementTree.Element) -> str:
    """One variable's row; ``kind``: the element holding its type, start, unit, min and max (FMI 2.0:
    the ScalarVariable's child; FMI 3.0: the variable itself)."""
    cells = [
        variable.get("name"), variable.get("causality", "local"), variable.get("variability", "continuous"),
        kind.tag + (f" ({kind.get('declaredType')})" if kind.get("declaredType") else ""),
        kind.get("unit", "as wired" if kind.tag in ("Real", "Float64") and variable.get("causality") != "independent" else ""), kind.get("start", ""), kind.get("min", ""), kind.get("max", ""),
        variable.get("description", ""),
    ]
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
