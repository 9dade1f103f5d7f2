"""The report's interactive plot: Plotly, its library written into the page
(``include_plotlyjs=True``), so the page stays one file that works offline.

Why Plotly: one pure-Python dependency (no server, no pandas), and its standalone HTML has
box zoom, pan, a unified cursor read-out of every signal at the pointer's time and a legend
whose click hides or shows a signal, out of the box.  The same marks as the matplotlib plot
(`cosim.present.plots`): quantity [unit] y labels, set-points dashed, sampled outputs as steps, an
event marker at each set-point change and disturbance step, the ±2 % settling band, the
settling instant, the overshoot peak and the controller's limits.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .metrics import event_metrics
from .plots import axis_label, label, limits, loop_events, near, sampled, setpoints, title

#: matplotlib's default colours, so the interactive plot and the PNG agree
_MATPLOTLIB_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]
#: the element id of the plot's div in the page
PLOT_ID = "interactive-plot"


def _loop_marks(fig, row: int, result: np.ndarray, metadata: Mapping, setpoint: str, measured: str) -> None:
    t, y = result["time"], result[measured]
    events = loop_events(result, metadata, setpoint)
    for ev, resp in zip(events, event_metrics(t, y, result[setpoint], events)):
        if ev.kind != "set-point" or ev.before == ev.after:
            continue
        step, target = ev.after - ev.before, ev.after
        fig.add_shape(type="rect", x0=ev.t0, x1=ev.t1, y0=target - 0.02 * abs(step), y1=target + 0.02 * abs(step),
                      row=row, col=1, fillcolor="#2ca02c", opacity=0.2, line_width=0)
        settle = resp.values["settling_time"]
        if settle == settle:
            fig.add_scatter(x=[ev.t0 + settle], y=[target], mode="markers+text", text=[f"settled {settle:.3g} s"],
                            textposition="top right", marker={"symbol": "line-ns-open", "size": 14, "color": "green"},
                            name=f"settling {ev.t0:g} s", showlegend=False, row=row, col=1)
        overshoot = resp.values["overshoot"]
        window = (t >= ev.t0) & (t <= ev.t1)
        if overshoot == overshoot and overshoot > 0 and window.any():
            i = np.flatnonzero(window)[np.argmax((y[window] - target) * np.sign(step))]
            fig.add_scatter(x=[t[i]], y=[y[i]], mode="markers+text", text=[f"overshoot {overshoot:.3g} %"],
                            textposition="middle right", marker={"symbol": "triangle-down", "size": 9, "color": "red"},
                            name=f"overshoot {ev.t0:g} s", showlegend=False, row=row, col=1)


def page_div(result: np.ndarray, panels: Sequence[Sequence[str]], *, scenario: str, metadata: Mapping) -> str:
    """The plot as an HTML ``<div>`` holding its own script and the Plotly library."""
    from plotly.subplots import make_subplots

    dashed = setpoints(metadata, result.dtype.names)
    loops = [list(p) for p in panels if len(p) == 2 and p[0] in dashed and p[1] not in dashed]
    fig = make_subplots(rows=len(panels), cols=1, shared_xaxes=True, vertical_spacing=0.06)
    t = result["time"]
    for row, signals in enumerate(panels, 1):
        for name in signals:
            fig.add_scatter(x=t, y=result[name], mode="lines", name=label(name, metadata), row=row, col=1,
                            line={"dash": "dash" if name in dashed else "solid",
                                  "shape": "hv" if sampled(name, metadata) else "linear"})
            for which, value in limits(name, metadata).items():
                if near(value, result[name]):
                    fig.add_hline(y=value, row=row, col=1, line={"dash": "dashdot", "color": "red", "width": 1},
                                  annotation_text=f"{which} = {value:g}", annotation_position="top right")
                else:   # far off the signal's range: named, not drawn (`cosim.present.plots.near`)
                    fig.add_annotation(text=f"{which} = {value:g} (off scale)", xref="x domain", yref="y domain",
                                       x=1, y=0 if which.endswith("min") else 1, showarrow=False,
                                       font={"color": "red", "size": 10}, row=row, col=1)
        if loops:
            for ev in {(e.t0, e.kind) for e in loop_events(result, metadata, loops[0][0]) if e.before != e.after}:
                fig.add_vline(x=ev[0], row=row, col=1,
                              line={"color": "gray", "width": 1, "dash": "solid" if ev[1] == "set-point" else "dot"})
        if list(signals) in loops:
            _loop_marks(fig, row, result, metadata, *signals)
        fig.update_yaxes(title_text=axis_label(signals, metadata), row=row, col=1)
    fig.update_xaxes(title_text="time [s]", row=len(panels), col=1)
    fig.update_layout(title=title(metadata, scenario), hovermode="x unified", height=260 * len(panels) + 120,
                      template="plotly_white", colorway=_MATPLOTLIB_COLOURS, legend={"orientation": "h", "y": -0.08})
    return fig.to_html(full_html=False, include_plotlyjs=True, div_id=PLOT_ID,
                       config={"displaylogo": False, "scrollZoom": True})
