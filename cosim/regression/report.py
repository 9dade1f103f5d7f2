"""The difference report of a comparison: one self-contained HTML page and a PNG beside it.

For each failing signal (every signal when none fails), two panels: the reference, the run and
the tube around the reference with every point outside it marked (the first and the worst
labelled); below, run − reference with the tube's bounds less the reference, where a small
difference shows.  A table gives every signal's verdict (rule, points out, first and worst
violation: time, run value, reference value, tube bounds) and, when given, the metric targets'.
The plot is interactive as the run report's is (Plotly written into the page: zoom, pan, the
cursor reading every trace, traces toggled from the legend; `cosim.present.interactive`), so the page
works offline and alone; the PNG (matplotlib) is the same panels for a CI log.
"""
from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..safeio import write_atomic
from .engine import Verdict
from .targets import MetricVerdict

#: at most this many signals are drawn (the table lists them all)
MOST_PLOTTED = 12
#: the element id of the plot's div in the page
PLOT_ID = "difference-plot"
#: reference, run, tube, violations: matplotlib's first two colours, as the run report's
COLOURS = {"reference": "#1f77b4", "run": "#ff7f0e", "tube": "rgba(44,160,44,0.25)", "out": "#d62728"}

_STYLE = """body{font-family:sans-serif;margin:2em;max-width:80em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}th,td{border:1px solid #bbb;padding:.25em .6em;text-align:left}
th{background:#eee}.failed{color:#b00;font-weight:bold}.passed{color:#070}.small{color:#666;font-size:90%}"""


def plotted(verdicts: Sequence[Verdict]) -> list[Verdict]:
    """The verdicts drawn: the failing ones (every one when none fails) with checked points, at most `MOST_PLOTTED`."""
    failing = [v for v in verdicts if not v.passed]
    return [v for v in (failing or verdicts) if v.trace is not None and len(v.trace.time)][:MOST_PLOTTED]


def _marks(v: Verdict) -> list[tuple[str, object]]:
    """The labelled violations: the first and the worst (one label when they are the same point)."""
    if v.first is not None and v.first == v.worst:
        return [("first and worst", v.first)]
    return [(what, point) for what, point in (("first", v.first), ("worst", v.worst)) if point is not None]


def _plotly_div(verdicts: Sequence[Verdict], title: str) -> str:
    from plotly.subplots import make_subplots

    shown = plotted(verdicts)
    titles = [t for v in shown for t in (f"{v.signal}: {'passed' if v.passed else 'FAILED'}",
                                         f"{v.signal}: run − reference")]
    fig = make_subplots(rows=2 * len(shown), cols=1, shared_xaxes=True, vertical_spacing=0.04 / max(len(shown), 1),
                        subplot_titles=titles)
    for k, v in enumerate(shown):
        tr, row = v.trace, 2 * k + 1
        out = np.flatnonzero(tr.out)
        for r, shift, legend in ((row, np.zeros_like(tr.reference), True), (row + 1, tr.reference, False)):
            group = {"legendgroup": v.signal, "row": r, "col": 1}
            fig.add_scatter(x=tr.time, y=tr.lower - shift, mode="lines", line={"width": 0}, hoverinfo="skip",
                            name=f"{v.signal} tube", showlegend=False, **group)
            fig.add_scatter(x=tr.time, y=tr.upper - shift, mode="lines", line={"width": 0}, fill="tonexty",
                            fillcolor=COLOURS["tube"], name=f"{v.signal} tube", showlegend=legend, **group)
            fig.add_scatter(x=tr.time, y=tr.reference - shift, mode="lines", name=f"{v.signal} reference",
                            line={"color": COLOURS["reference"]}, showlegend=legend, **group)
            fig.add_scatter(x=tr.time, y=tr.value - shift, mode="lines", name=f"{v.signal} run",
                            line={"color": COLOURS["run"], "dash": "dot"}, showlegend=legend, **group)
            if len(out):
                fig.add_scatter(x=tr.time[out], y=(tr.value - shift)[out], mode="markers",
                                marker={"color": COLOURS["out"], "symbol": "x", "size": 7},
                                name=f"{v.signal} outside ({len(out)})", showlegend=legend, **group)
            for what, point in _marks(v):
                fig.add_annotation(x=point.time, y=point.value - (0.0 if legend else point.reference),
                                   text=f"{what}: t = {point.time:.6g} s", showarrow=True, arrowcolor=COLOURS["out"],
                                   font={"color": COLOURS["out"]}, row=r, col=1)
        fig.update_yaxes(title_text=v.signal, row=row, col=1)
        fig.update_yaxes(title_text="run − reference", row=row + 1, col=1)
    fig.update_xaxes(title_text="time [s]", row=2 * len(shown), col=1)
    fig.update_layout(title=title, hovermode="x unified", height=300 * 2 * len(shown) + 140, template="plotly_white",
                      legend={"orientation": "h", "y": -0.04})
    return fig.to_html(full_html=False, include_plotlyjs=True, div_id=PLOT_ID,
                       config={"displaylogo": False, "scrollZoom": True})


def write_png(verdicts: Sequence[Verdict], path: Path, title: str) -> Path:
    """The same panels as the page's plot, with matplotlib."""
    import matplotlib
    import matplotlib.pyplot as plt

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "png"):
        matplotlib.use("Agg")
    shown = plotted(verdicts)
    fig, axes = plt.subplots(2 * len(shown), 1, figsize=(10, 2.6 * 2 * len(shown) + 0.6), sharex=True, squeeze=False)
    for k, v in enumerate(shown):
        tr = v.trace
        top, diff = axes[2 * k, 0], axes[2 * k + 1, 0]
        top.fill_between(tr.time, tr.lower, tr.upper, color="tab:green", alpha=0.25, lw=0, label="tube")
        top.plot(tr.time, tr.reference, color="tab:blue", label="reference")
        top.plot(tr.time, tr.value, color="tab:orange", ls=":", label="run")
        diff.fill_between(tr.time, tr.lower - tr.reference, tr.upper - tr.reference, color="tab:green", alpha=0.25,
                          lw=0)
        diff.plot(tr.time, tr.value - tr.reference, color="tab:orange", ls=":")
        diff.axhline(0.0, color="tab:blue", lw=0.8)
        out = np.flatnonzero(tr.out)
        if len(out):
            top.plot(tr.time[out], tr.value[out], "x", color="tab:red", label=f"outside ({len(out)})")
            diff.plot(tr.time[out], (tr.value - tr.reference)[out], "x", color="tab:red")
        for what, point in _marks(v):
            top.annotate(f"{what}: t = {point.time:.6g} s", (point.time, point.value), color="tab:red", fontsize=8,
                         xytext=(8, 8), textcoords="offset points")
        top.set_title(f"{v.signal}: {'passed' if v.passed else 'FAILED'} ({v.rule})", fontsize=9, loc="left")
        top.set_ylabel(v.signal)
        diff.set_ylabel("run − reference")
        top.legend(fontsize=8, loc="best")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _point(p) -> str:
    return "" if p is None else (f"t = {p.time:.10g} s: run {p.value:.8g}, reference {p.reference:.8g}, "
                                 f"tube [{p.lower:.8g}, {p.upper:.8g}]")


def _table(rows: Sequence[Sequence[str]], header: Sequence[str], states: Sequence[bool]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(f"<tr class={'passed' if ok else 'failed'}>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row)
                   + "</tr>" for row, ok in zip(rows, states))
    return f"<table><tr>{head}</tr>{body}</table>"


def render(verdicts: Sequence[Verdict], *, title: str, metrics: Sequence[MetricVerdict] = (),
           png: str | None = None) -> str:
    """The page as a string (module docstring)."""
    failed = [v for v in verdicts if not v.passed] + [m for m in metrics if not m.passed]
    signal_rows = [(v.signal, "passed" if v.passed else "FAILED", v.rule, f"{v.out} of {v.checked}",
                    f"{v.max_abs:.3g}", v.problem or _point(v.first), _point(v.worst)) for v in verdicts]
    metric_rows = [(m.signal, m.metric, "passed" if m.passed else "FAILED", f"{m.measured:.6g}",
                    f"{m.expected:g} ± {m.tolerance:g}", m.window, m.why) for m in metrics]
    shown = plotted(verdicts)
    plot = _plotly_div(verdicts, title) if shown else "<p>No signal has points to draw.</p>"
    note = "" if len(shown) == len([v for v in verdicts if not v.passed] or verdicts) else \
        f"<p class=small>The first {len(shown)} are drawn; the table lists every signal.</p>"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title><style>{_STYLE}</style></head>
<body>
<h1>{html.escape(title)}</h1>
<p class={'failed' if failed else 'passed'}>{len(failed)} failing of {len(verdicts) + len(metrics)} checks.</p>
<h2>Signals</h2>
{_table(signal_rows, ("signal", "verdict", "rule", "points outside", "max |run − ref|", "first violation",
                      "worst violation"), [v.passed for v in verdicts])}
{"<h2>Metric targets</h2>" + _table(metric_rows, ("signal", "metric", "verdict", "measured", "target", "window",
                                                   "why undefined"), [m.passed for m in metrics]) if metrics else ""}
<h2>Plot</h2>
<p class=small>The tube (green) around the reference (blue), the run (orange, dotted), points outside the tube
(red ×); below each, run − reference. Drag to zoom (double-click: back), the cursor reads every trace, a click
on a legend entry hides or shows that signal.{f' The same panels as a PNG: <code>{html.escape(png)}</code>.' if png else ''}</p>
{note}{plot}
</body></html>
"""


def write_report(verdicts: Sequence[Verdict], path: str | Path, *, title: str,
                 metrics: Sequence[MetricVerdict] = ()) -> tuple[Path, Path]:
    """Write the page to ``path`` and the PNG beside it (``path`` with .png); returns both."""
    path = Path(path)
    png = path.with_suffix(".png")
    if plotted(verdicts):
        write_png(verdicts, png, title)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, render(verdicts, title=title, metrics=metrics, png=png.name if png.exists() else None))
    return path, png
