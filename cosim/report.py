"""``cosim report RESULT``: one self-contained HTML page per run, for a reviewer of a control study.

The page holds the plot (`cosim.plots`, PNG embedded as a data URI, so the file can be mailed
or archived alone), the metrics of every control loop per event (`cosim.metrics.find_events`
and `event_metrics`: each set-point change and each step of a disturbance, a signal driving
a plant input ``d``, ``d1``, ...), the parameters applied with the file and line each came
from, the FMUs, and the rest of the run's metadata JSON.  Nothing is fetched at view time:
no scripts, no style sheets or fonts from elsewhere.
"""
from __future__ import annotations

import base64
import html
import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .errors import SetupError
from .metrics import EVENT_METRICS, UNITS, event_metrics, find_events
from .plots import default_panels, disturbances, figure, label, setpoints, title
from .safeio import write_atomic

_STYLE = """body{font-family:sans-serif;margin:2em;max-width:70em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}th,td{border:1px solid #bbb;padding:.25em .6em;text-align:right}
th{background:#eee}td.t{text-align:left}img{max-width:100%;border:1px solid #ddd}
.undefined{color:#666;font-size:90%}pre{background:#f6f6f6;padding:1em;overflow:auto}"""


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
        head = "".join(f"<th>{html.escape(k)}{' [' + UNITS[k] + ']' if k in UNITS else ''}</th>"
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
                     f"<table><tr><th>#</th><th>event</th><th>window [s]</th>{head}</tr>\n" + "\n".join(body)
                     + "</table>\n" + (f"<ul class=undefined>{''.join(notes)}</ul>" if notes else ""))
    if not parts:
        return "<p>No control loop found (no component with inputs r and y), so no loop metrics.</p>"
    return (f"<p>e = set-point − measured; settling into ±2 % of the set-point step (after a disturbance: "
            f"of the last set-point step); disturbances: {html.escape(', '.join(load) or 'none found')}.</p>"
            + "\n".join(parts))


def _table(rows: Sequence[Sequence[str]], header: Sequence[str]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td class=t>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def render(result: np.ndarray, metadata: Mapping, *, source: str,
           panels: Sequence[Sequence[str]] | None = None) -> str:
    """The page as a string (see the module docstring)."""
    names = [n for n in result.dtype.names if n != "time"]
    scenario = metadata.get("scenario") or Path(source).stem
    all_panels = list(panels) if panels else default_panels(metadata, names)
    loops = [p for p in default_panels(metadata, names) if len(p) == 2 and p[0] in setpoints(metadata, names)]
    origins = metadata.get("parameter_origins", {})
    parameters = [(k, v, origins.get(k, "")) for k, v in metadata.get("parameters", {}).items()]
    components = [(k, Path(c.get("fmu", "")).name, c.get("interface", ""), c.get("generation_tool", ""), c.get("guid", ""))
                  for k, c in metadata.get("components", {}).items()]
    run = [(k, metadata.get(k)) for k in ("status", "message", "start_time", "stop_time", "step_size",
                                          "step_size_source", "algorithm", "steps", "loop_seconds", "finished_at",
                                          "system", "parameter_sets") if k in metadata]
    heading = title(metadata, scenario)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(heading)}</title><style>{_STYLE}</style></head>
<body>
<h1>{html.escape(heading)}</h1>
<p>Result <code>{html.escape(source)}</code>: {len(result)} samples, t = {result["time"][0]:g} … {result["time"][-1]:g} s,
status <b>{html.escape(str(metadata.get("status", "unknown")))}</b>.</p>
<h2>Plot</h2>
<img id="plot" alt="{html.escape(heading)}" src="data:image/png;base64,{_png(result, all_panels, scenario, metadata)}">
<h2>Metrics per event</h2>
{_metrics_section(result, metadata, loops)}
<h2>Parameters applied</h2>
{_table(parameters, ("parameter", "value", "from"))}
<h2>FMUs</h2>
{_table(components, ("component", "FMU", "interface", "generated by", "GUID"))}
<h2>Run</h2>
{_table(run, ("", ""))}
<h2>Metadata (the run's JSON)</h2>
<pre>{html.escape(json.dumps(metadata, indent=1, default=str))}</pre>
</body></html>
"""


def write_report(result_path: str | Path, html_path: str | Path,
                 panels: Sequence[Sequence[str]] | None = None) -> Path:
    """Read a result and its metadata JSON and write the page (``panels``: as `cosim.plots.plot`)."""
    from .results import read

    result_path, html_path = Path(result_path), Path(html_path)
    result = read(result_path)
    page = render(result, read_metadata(result_path), source=str(result_path), panels=panels)
    html_path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(html_path, page)
    return html_path
