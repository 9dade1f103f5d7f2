"""Plots of a run a control engineer can read, from the samples and the run's metadata JSON.

The metadata (`cosim.run.simulation`) gives each recorded connector's unit and description and
the connections.  From them: the title names the scenario and the parameter sets applied;
each panel's y label carries its signals' units; a legend entry is the signal's name and a
description (a block's generic "Step output" says little, so such a signal is described by
the input it drives, e.g. "Set-point"); set-points (a controller's input ``r``, ``r1``, ...
and the signals driving it) are dashed.  `default_panels` chooses what to
show when the user names nothing: for each controller input pair ``r<k>``/``y<k>`` the
set-point with the controlled variable, then each controller's outputs ``u…``, then the
disturbances (signals driving a plant input ``d``, ``d1``, ...).

As a scope reads: a y label is the quantity and its unit (`axis_label`); a signal whose FMU
declares no unit takes the unit of what it is wired to, "as wired" (`units`); each set-point
change and disturbance step is a vertical marker; a loop's panel shows, per set-point step, the
±2 % settling band, the settling instant and the overshoot peak (`cosim.present.metrics`); a controller
output shows its limits ``u_min``/``u_max`` when the run set them; a sampled output (FMI
variability discrete: held between samples) is drawn as steps.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..model.structure import Plan
from ..record.metadata import signal_info
from .metrics import event_metrics, find_events

_SETPOINT_INPUT = re.compile(r"r\d*")
_MEASUREMENT_INPUT = re.compile(r"y\d*")
_CONTROLLER_OUTPUT = re.compile(r"u\d*")
_DISTURBANCE_INPUT = re.compile(r"d\d*")
#: the index of an FMI 3.0 array element's name (``[2,3]`` of ``A[2,3]``)
_ARRAY_INDEX = re.compile(r"\[\d+(,\d+)*\]$")
#: blocks whose output has the unit of their inputs (a dimensionless gain, a sum)
_UNIT_PRESERVING = {"Gain", "Sum"}


def connections(metadata: Mapping) -> list[tuple[str, str, bool]]:
    """(source, destination, identity) of each connection; identity: it has no transformation
    (the metadata's ``transforms`` names those that have one)."""
    transforms = metadata.get("transforms", {})
    out = []
    for text in metadata.get("connections", []):
        src, _, dst = text.partition(" -> ")
        out.append((src, dst, text not in transforms))
    return out


def _split(name: str) -> tuple[str, str]:
    component, _, variable = name.rpartition(".")
    return component, variable


def setpoints(metadata: Mapping, names: Sequence[str] = ()) -> set[str]:
    """Signals that are set-points: a controller's input ``r<k>`` (connected, or among ``names``
    beside a ``y<k>`` of the same component) and what drives it."""
    found = set()
    for src, dst, _ in connections(metadata):
        if _SETPOINT_INPUT.fullmatch(_split(dst)[1]):
            found |= {src, dst}
    for n in names:
        component, variable = _split(n)
        if _SETPOINT_INPUT.fullmatch(variable) and f"{component}.y{variable[1:]}" in names:
            found.add(n)
    return found


def _generic(descriptions: Mapping[str, str]) -> set[str]:
    """Descriptions that outputs of two or more components share: a block's generic text
    ("Step output", "Weighted sum of the inputs") that tells nothing about this signal."""
    seen: dict[str, set[str]] = {}
    for name, text in descriptions.items():
        seen.setdefault(text, set()).add(_split(name)[0])
    return {text for text, components in seen.items() if len(components) > 1}


def label(signal: str, metadata: Mapping, width: int = 48) -> str:
    """``signal — description``: its FMU variable's own description, or, where that is a block's
    generic text or missing, that of the first input it drives that has a specific one
    ("Set-point")."""
    descriptions = metadata.get("descriptions", {})
    generic = _generic(descriptions)
    text = descriptions.get(signal, "")
    if not text or text in generic:
        driven = [descriptions[dst] for src, dst, _ in connections(metadata)
                  if src == signal and descriptions.get(dst) and descriptions[dst] not in generic]
        text = driven[0] if driven else text
    if len(text) > width:
        text = text[:width - 1].rstrip() + "…"
    return f"{signal} — {text}" if text else signal


def disturbances(metadata: Mapping, names: Sequence[str]) -> list[str]:
    """Recorded signals that drive a disturbance input ``d<k>`` of some component."""
    return list(dict.fromkeys(src for src, dst, _ in connections(metadata)
                              if _DISTURBANCE_INPUT.fullmatch(_split(dst)[1]) and src in names))


def units(metadata: Mapping) -> dict[str, tuple[str, bool]]:
    """Each signal's unit and whether it is taken "as wired": the FMU's own unit, else that of a
    signal it is connected to unchanged (either way), joined to through a `_UNIT_PRESERVING`
    block (its inputs and output) or compared with by a controller (``y<k>`` with ``r<k>``),
    found through any chain of those."""
    declared = {n: u for n, u in metadata.get("units", {}).items() if u}
    links: dict[str, set[str]] = {}

    def link(a: str, b: str) -> None:
        links.setdefault(a, set()).add(b)
        links.setdefault(b, set()).add(a)

    for src, dst, identity in connections(metadata):
        if identity:
            link(src, dst)
    blocks = {c for c, info in metadata.get("components", {}).items()
              if Path(str(info.get("fmu", ""))).stem in _UNIT_PRESERVING}
    signals = set(metadata.get("units", {})) | set(links)
    for block in blocks:
        ends = sorted(n for n in signals if _split(n)[0] == block)
        for other in ends[1:]:
            link(ends[0], other)
    for name in signals:   # a controller compares y<k> with r<k>: one unit
        component, variable = _split(name)
        if _SETPOINT_INPUT.fullmatch(variable) and f"{component}.y{variable[1:]}" in signals:
            link(name, f"{component}.y{variable[1:]}")
    found = {n: (u, False) for n, u in declared.items()}
    frontier = list(declared)
    while frontier:
        here = frontier.pop(0)
        for there in sorted(links.get(here, ())):
            if there not in found:
                found[there] = (found[here][0], True)
                frontier.append(there)
    return found


def quantity(signal: str, metadata: Mapping) -> str:
    """What a signal measures, for an axis: its description (`label`'s) up to the first comma or
    parenthesis ("Controller output, held between samples" → "Controller output")."""
    text = label(signal, metadata, width=200).partition(" — ")[2]
    return re.split(r",|\(|;", text)[0].strip() or signal


def axis_label(signals: Sequence[str], metadata: Mapping) -> str:
    """``quantity [unit]`` of a panel: the quantity of its first signal that is not a set-point,
    the units of all; "(as wired)" when a unit comes from a connected signal; "(no unit
    declared)" when none has one."""
    found = units(metadata)
    dashed = setpoints(metadata, signals)
    main = next((s for s in signals if s not in dashed), signals[0])
    what = quantity(main, metadata)
    present = [found[s] for s in signals if s in found]
    if not present:
        return f"{what} (no unit declared)"
    text = ", ".join(f"[{u}]" for u in dict.fromkeys(u for u, _ in present))
    return f"{what} {text}" + (" (as wired)" if all(wired for _, wired in present) else "")


#: the most characters of a y label line: a panel is 2.2 inches tall, a 9-point character about 5 points wide
LABEL_LINE = 30


def fitted(text: str) -> str:
    """A y label broken into lines of at most `LABEL_LINE` characters (at spaces), so that it
    stays within its panel's height and never runs into the next panel's label."""
    import textwrap

    return "\n".join(textwrap.wrap(text, LABEL_LINE, break_long_words=False)) or text


def sampled(signal: str, metadata: Mapping) -> bool:
    """Whether the signal is held between samples: FMI variability discrete (``discrete`` in the
    metadata), or its description says so (metadata written before that was recorded)."""
    return signal in metadata.get("discrete", ()) or "held between samples" in metadata.get(
        "descriptions", {}).get(signal, "")


def limits(signal: str, metadata: Mapping) -> dict[str, float]:
    """A controller output's limits set for the run: ``u_min``/``u_max`` (per output ``u<k>``:
    ``u<k>_min`` first) among the parameters applied, when finite and not a "none" default."""
    component, variable = _split(signal)
    if not _CONTROLLER_OUTPUT.fullmatch(variable):
        return {}
    parameters = metadata.get("parameters", {})
    out = {}
    for side in ("min", "max"):
        for key in (f"{component}.{variable}_{side}", f"{component}.u_{side}"):
            value = parameters.get(key)
            if isinstance(value, (int, float)) and abs(value) < 1e9:
                out[key.rpartition(".")[2]] = float(value)
                break
    return out


def default_panels(metadata: Mapping, names: Sequence[str]) -> list[list[str]]:
    """Set-point with controlled variable for each controller loop, then each controller's
    outputs; every recorded output alone in its panel (an array's elements together) when no
    controller is found."""
    recorded = set(names)
    sources = {dst: (src, identity) for src, dst, identity in connections(metadata)}
    loops, outputs = [], []
    controllers = sorted({_split(dst)[0] for dst in sources if _SETPOINT_INPUT.fullmatch(_split(dst)[1])}
                         | {_split(n)[0] for n in names if _SETPOINT_INPUT.fullmatch(_split(n)[1])},
                         key=lambda c: min((i for i, n in enumerate(names) if n.startswith(c + ".")), default=0))
    for c in controllers:
        for r in sorted(n for n in recorded if _split(n)[0] == c and _SETPOINT_INPUT.fullmatch(_split(n)[1])):
            y = f"{c}.y{_split(r)[1][1:]}"
            if y not in recorded:
                continue
            # show what drives the inputs when the connection passes values unchanged
            pair = [sources[n][0] if n in sources and sources[n][1] and sources[n][0] in recorded else n
                    for n in (r, y)]
            if pair not in loops:
                loops.append(pair)
        u = [n for n in names if _split(n)[0] == c and _CONTROLLER_OUTPUT.fullmatch(_split(n)[1])]
        if u:
            outputs.append(u)
    load = disturbances(metadata, names)
    if loops:
        return loops + outputs + ([load] if load else [])
    driven = {src for src, _, _ in connections(metadata)}
    return _by_array([n for n in names if n in driven] or list(names))


def _by_array(names: Sequence[str]) -> list[list[str]]:
    """One panel per signal, the elements of one FMI 3.0 array (``A[1,1]`` .. ``A[2,3]``) in one."""
    panels: dict[str, list[str]] = {}
    for name in names:
        panels.setdefault(_ARRAY_INDEX.sub("", name), []).append(name)
    return list(panels.values())


def title(metadata: Mapping, scenario: str) -> str:
    """``scenario — set1, set2`` (the parameter sets applied, by file stem)."""
    sets = [Path(p).stem for p in metadata.get("parameter_sets", [])]
    return scenario + (f" — {', '.join(sets)}" if sets else "")


def plain(text: str) -> str:
    """``text`` as matplotlib shows it literally: every ``$`` escaped, so a name, description or
    unit holding ``$…$`` (or a lone ``$``) is never parsed as mathtext, which fails on what is
    not TeX."""
    return text.replace("$", r"\$")


def loop_events(result: np.ndarray, metadata: Mapping, setpoint: str):
    """The set-point's and the disturbances' events (`cosim.present.metrics.find_events`)."""
    load = disturbances(metadata, result.dtype.names)
    return find_events(result["time"], (setpoint, result[setpoint]), {d: result[d] for d in load})


def _mark_events(ax, result: np.ndarray, metadata: Mapping, loops: Sequence[Sequence[str]]) -> None:
    """A vertical line at each set-point change (solid) and disturbance step (dotted)."""
    seen = set()
    for setpoint, _ in loops:
        for ev in loop_events(result, metadata, setpoint):
            if ev.before == ev.after or (ev.signal, ev.t0) in seen:
                continue
            seen.add((ev.signal, ev.t0))
            ax.axvline(ev.t0, color="0.35", lw=0.8, ls="-" if ev.kind == "set-point" else ":")


def _annotate_loop(ax, result: np.ndarray, metadata: Mapping, setpoint: str, measured: str) -> None:
    """Per set-point step: the ±2 % settling band over its window, the settling instant and the
    overshoot peak, from `cosim.present.metrics.event_metrics`; each disturbance step named."""
    t, y = result["time"], result[measured]
    events = loop_events(result, metadata, setpoint)
    for ev, row in zip(events, event_metrics(t, y, result[setpoint], events)):
        if ev.kind != "set-point":
            ax.annotate(plain(f"{ev.signal} {ev.before:g} → {ev.after:g}"), (ev.t0, 1), xycoords=("data", "axes fraction"),
                        xytext=(3, -10), textcoords="offset points", fontsize=7, color="0.3")
            continue
        if ev.before == ev.after:
            continue
        step, target = ev.after - ev.before, ev.after
        half = 0.02 * abs(step)
        ax.fill_between([ev.t0, ev.t1], target - half, target + half, color="C2", alpha=0.15, lw=0,
                        label="±2 % settling band" if not ax.get_legend_handles_labels()[1].count("±2 % settling band") else None)
        settle = row.values["settling_time"]
        if settle == settle:
            ax.plot([ev.t0 + settle], [target], "|", color="C2", markersize=14, mew=2)
            ax.annotate(f"settled at {ev.t0 + settle:.4g} s ({settle:.3g} s after the step)", (ev.t0 + settle, target),
                        xytext=(4, 6), textcoords="offset points", fontsize=7, color="C2")
        overshoot = row.values["overshoot"]
        window = (t >= ev.t0) & (t <= ev.t1)
        if overshoot == overshoot and overshoot > 0 and window.any():
            i = np.flatnonzero(window)[np.argmax((y[window] - target) * np.sign(step))]
            ax.plot([t[i]], [y[i]], "v" if step > 0 else "^", color="C3", markersize=6)
            ax.annotate(f"overshoot {overshoot:.3g} %", (t[i], y[i]), xytext=(8, -10), textcoords="offset points",
                        fontsize=7, color="C3")


def near(value: float, values: np.ndarray) -> bool:
    """Whether a limit is within one span of the signal's range (drawn), not far off it (named)."""
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    span = max(hi - lo, 1e-9 * max(1.0, abs(hi)))
    return lo - span <= value <= hi + span


def _draw_limits(ax, signal: str, values: np.ndarray, metadata: Mapping) -> None:
    """The controller output's limits as lines; one far off the signal's range (more than its
    span beyond it) is named in the legend instead (an entry with no data: text in a corner hid
    under the legend), so the signal stays readable."""
    for name, value in limits(signal, metadata).items():
        if near(value, values):
            ax.axhline(value, color="C3", lw=0.9, ls="-.")
            ax.annotate(plain(f"{name} = {value:g}"), (1, value), xycoords=("axes fraction", "data"),
                        xytext=(-3, 2), textcoords="offset points", ha="right", fontsize=7, color="C3")
        else:
            ax.plot([], [], color="C3", lw=0.9, ls="-.", label=plain(f"{name} = {value:g} (off scale)"))


def figure(result: np.ndarray, panels: Sequence[Sequence[str]], *, scenario: str, metadata: Mapping | None = None):
    """A matplotlib Figure: one subplot per panel, its signals overlaid against time (set-points
    dashed, sampled signals as steps), marked and labelled as the module says, each text shown
    literally (`plain`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metadata = metadata or {}
    names = result.dtype.names
    dashed = setpoints(metadata, names)
    loops = [p for p in panels if len(p) == 2 and p[0] in dashed and p[1] not in dashed]
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(9, 1.2 + 2.2 * len(panels)), squeeze=False)
    for ax, signals in zip(axes[:, 0], panels):
        for name in signals:
            ax.plot(result["time"], result[name], lw=1.3, ls="--" if name in dashed else "-",
                    drawstyle="steps-post" if sampled(name, metadata) else "default",
                    label=plain(label(name, metadata)))
            _draw_limits(ax, name, result[name], metadata)
        _mark_events(ax, result, metadata, loops)
        if list(signals) in [list(p) for p in loops]:
            _annotate_loop(ax, result, metadata, *signals)
        ax.set_ylabel(plain(fitted(axis_label(signals, metadata))), fontsize=9)
        ax.legend(loc="best", fontsize="small")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    fig.align_ylabels(axes[:, 0])
    axes[0, 0].set_title(plain(title(metadata, scenario)))
    fig.tight_layout()
    return fig


def plot(result: np.ndarray, panels: Sequence[Sequence[str]], path: str | Path, *, scenario: str,
         metadata: Mapping | None = None) -> Path:
    """`figure` written as an image (format from the suffix), through ``<path>.part`` and one
    rename (`cosim.safeio.atomic_path`): a reader never sees half a plot."""
    import matplotlib.pyplot as plt

    from ..safeio import atomic_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = figure(result, panels, scenario=scenario, metadata=metadata)
    try:
        with atomic_path(path) as part:
            fig.savefig(part, dpi=110, format=path.suffix[1:] or "png")
    finally:
        plt.close(fig)
    return path


def signal_units(plan: Plan) -> dict[str, tuple[str, bool]]:
    """Each recorded signal of a plan's runs with its unit and whether it is "as wired" (`units`)."""
    info = signal_info(plan)
    return units({"units": dict(plan.units), "connections": info["connections"], "transforms": info["transforms"],
                  "components": {name: {"fmu": str(d.path)} for name, d in plan.fmus.items()}})


def plotted(plan: Plan, names: list[str]) -> list[str]:
    """The signals a default plot shows: for a single FMU its connectors once (not again under
    the output aliases that `cosim.read.single.fmu_structure` adds), for a system all."""
    if not plan.files.single_fmu:
        return names
    return [n for n in names if n not in plan.system_outputs]
