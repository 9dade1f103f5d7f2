"""``cosim report RESULT``: one self-contained HTML page per run, for a reviewer of a control study.

The page holds the plot, interactive (`cosim.present.interactive`: zoom, pan, cursor read-out, signals
toggled; Plotly's library written into the page) and as a static PNG (`cosim.present.plots`, a data
URI), so the file can be mailed or archived alone and works offline; the metrics of every
control loop per event (`cosim.present.metrics.find_events` and `event_metrics`: each set-point change
and each step of a disturbance, a signal driving a plant input ``d``, ``d1``, ...), with units
from the measured signal's (IAE in unit·s, ...); the parameters applied, a mode parameter by
its item name (``METHOD3``), with the file and line each came from; the FMUs; the run's facts
for people (seconds to three significant digits, lists joined).  Paths are as the metadata
holds them: relative, never those of the machine that ran it.  Nothing is fetched at view
time: no script, style sheet or font comes from elsewhere.
"""
from __future__ import annotations

import base64
import html
import io
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..errors import SetupError
from .interactive import page_div
from .metrics import EVENT_METRICS, event_metrics, find_events, metric_unit
from .plots import default_panels, disturbances, figure, label, setpoints, title, units
from ..safeio import write_atomic

_STYLE = """body{font-family:sans-serif;margin:2em;max-width:70em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}th,td{border:1px solid #bbb;padding:.25em .6em;text-align:right}
th{background:#eee}td.t{text-align:left}img{max-width:100%;border:1px solid #ddd}
.undefined{color:#666;font-size:90%}"""


def read_metadata(result: Path) -> dict:
    """The run's metadata JSON beside ``result`` (`cosim run` writes both)."""
    path = result.with_suffix(".json")
    if not path.is_file():
        raise SetupError("no metadata JSON beside the result (cosim run writes X.json beside X.csv).",
                         file=str(path))
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise SetupError(f"the metadata is not JSON ({e}).", file=str(path)) from None


def _png(result: np.ndarray, panels: Sequence[Sequence[str]], scenario: str, metadata: Mapping) -> str:
    import matplotlib.pyplot as plt

    fig = figure(result, panels, scenario=scenario, metadata=metadata)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _cell(value: float) -> str:
    return f"{value:.5g}" if value == value else "–"


def _metrics_section(result: np.ndarray, metadata: Mapping, loops: Sequence[Sequence[str]]) -> str:
    names = list(result.dtype.names)
    load = disturbances(metadata, names)
    parts = []
    for setpoint, measured in loops:
        events = find_events(result["time"], (setpoint, result[setpoint]), {d: result[d] for d in load})
        rows = event_metrics(result["time"], result[measured], result[setpoint], events)
        unit = units(metadata).get(measured, (None, False))[0]
        head = "".join(f"<th>{html.escape(k)}{' [' + html.escape(metric_unit(k, unit)) + ']' if metric_unit(k, unit) else ''}</th>"
                       for k in EVENT_METRICS)
        body = []
        notes = []
        for i, (ev, row) in enumerate(zip(events, rows), 1):
            cells = "".join(f"<td>{_cell(row.values[k])}</td>" for k in EVENT_METRICS)
            body.append(f"<tr><td>{i}</td><td class=t>{html.escape(ev.describe())}</td>"
                        f"<td>{ev.t0:g} – {ev.t1:g}</td>{cells}</tr>")
            notes += [f"<li>event {i}, {html.escape(', '.join(keys))}: {html.escape(why)}</li>" for keys, why in row.grouped()]
        parts.append(f"<h3>{html.escape(label(measured, metadata))} following "
                     f"{html.escape(label(setpoint, metadata))}</h3>\n"
                     + ("" if unit else f"<p class=undefined>{html.escape(measured)} declares no unit (none as wired "
                                        "either): the error is taken as a pure number, so IAE is in s.</p>\n")
                     + f"<table><tr><th>#</th><th>event</th><th>window [s]</th>{head}</tr>\n" + "\n".join(body)
                     + "</table>\n" + (f"<ul class=undefined>{''.join(notes)}</ul>" if notes else ""))
    if not parts:
        return "<p>No control loop found (no component with inputs r and y), so no loop metrics.</p>"
    return (f"<p>e = set-point − measured; settling into ±2 % of the set-point step (after a disturbance: "
            f"of the last set-point step); disturbances: {html.escape(', '.join(load) or 'none found')}.</p>"
            + "\n".join(parts))


_ENUMERATION = re.compile(r"\((\d+ = \w+(?:, \d+ = \w+)*)\)\s*$")


def parameter_value(name: str, value: object, metadata: Mapping) -> str:
    """A parameter's value for people: a mode parameter by its item name (``METHOD3``, from the
    ``(1 = METHOD1, ...)`` its FMU's description lists), a number with its unit (``7.17 s``)."""
    description = metadata.get("parameter_descriptions", {}).get(name, "")
    found = _ENUMERATION.search(description)
    if found and isinstance(value, int):
        items = dict(item.split(" = ") for item in found.group(1).split(", "))
        if str(value) in items:
            return f"{items[str(value)]} ({value})"
    text = f"{value:g}" if isinstance(value, float) else str(value)
    unit = metadata.get("parameter_units", {}).get(name)
    return f"{text} {unit}" if unit and unit != "1" and isinstance(value, (int, float)) else text


def _seconds(value: object) -> str:
    return f"{value:.3g} s" if isinstance(value, (int, float)) else str(value)


#: the run's facts shown, each with its name for people and how its value reads
_RUN_FACTS = (("status", "status", str), ("message", "message", str), ("start_time", "start time", _seconds),
              ("stop_time", "stop time", _seconds), ("step_size", "step size", _seconds),
              ("step_size_source", "step size from", str), ("algorithm", "algorithm", str),
              ("steps", "steps", str), ("loop_seconds", "wall time of the stepping loop", _seconds),
              ("finished_at", "finished at", str), ("system", "system", str),
              ("parameter_sets", "parameter sets", lambda v: ", ".join(map(str, v)) or "none"))


def run_facts(metadata: Mapping) -> list[tuple[str, str]]:
    """(name, value) of each run fact the metadata holds, formatted for people."""
    return [(name, show(metadata[key])) for key, name, show in _RUN_FACTS
            if key in metadata and metadata[key] not in (None, "")]


def _table(rows: Sequence[Sequence[str]], header: Sequence[str]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td class=t>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def render(result: np.ndarray, metadata: Mapping, *, source: str,
           panels: Sequence[Sequence[str]] | None = None, before: str = "") -> str:
    """The page as a string (see the module docstring); ``before``: HTML put between the heading
    and the run (``cosim tune``'s summary of the tuning)."""
    names = [n for n in result.dtype.names if n != "time"]
    scenario = metadata.get("scenario") or Path(source).stem
    all_panels = list(panels) if panels else default_panels(metadata, names)
    loops = [p for p in default_panels(metadata, names) if len(p) == 2 and p[0] in setpoints(metadata, names)]
    origins = metadata.get("parameter_origins", {})
    parameters = [(k, parameter_value(k, v, metadata), origins.get(k, ""))
                  for k, v in metadata.get("parameters", {}).items()]
    components = [(k, c.get("fmu", ""), c.get("interface", ""), c.get("generation_tool", ""), c.get("guid", ""))
                  for k, c in metadata.get("components", {}).items()]
    heading = title(metadata, scenario)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(heading)}</title><style>{_STYLE}</style></head>
<body>
<h1>{html.escape(heading)}</h1>
{before}<p>Result <code>{html.escape(Path(source).name)}</code>: {len(result)} samples, t = {result["time"][0]:g} … {result["time"][-1]:g} s,
status <b>{html.escape(str(metadata.get("status", "unknown")))}</b>.</p>
<h2>Plot</h2>
<p class=undefined>Drag to zoom (double-click: back), shift-drag or the toolbar to pan, the cursor reads every
signal at its time, a click on a legend entry hides or shows that signal.</p>
{page_div(result, all_panels, scenario=scenario, metadata=metadata)}
<details><summary>The same plot as a static image (for print or mail)</summary>
<img id="plot" alt="{html.escape(heading)}" src="data:image/png;base64,{_png(result, all_panels, scenario, metadata)}">
</details>
<h2>Metrics per event</h2>
{_metrics_section(result, metadata, loops)}
<h2>Parameters applied</h2>
{_table(parameters, ("parameter", "value", "from"))}
<h2>FMUs</h2>
{_table(components, ("component", "FMU", "interface", "generated by", "GUID"))}
<h2>Run</h2>
{_table(run_facts(metadata), ("", ""))}
<p>The run's full metadata: <code>{html.escape(Path(source).with_suffix(".json").name)}</code> beside the result.</p>
</body></html>
"""


def write_report(result_path: str | Path, html_path: str | Path,
                 panels: Sequence[Sequence[str]] | None = None, before: str = "") -> Path:
    """Read a result and its metadata JSON and write the page (``panels``: as `cosim.present.plots.plot`;
    ``before``: as `render`'s)."""
    from ..record.results import read

    result_path, html_path = Path(result_path), Path(html_path)
    result = read(result_path)
    page = render(result, read_metadata(result_path), source=str(result_path), panels=panels, before=before)
    html_path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(html_path, page)
    return html_path
