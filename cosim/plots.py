"""Plots of a run a control engineer can read, from the samples and the run's metadata JSON.

The metadata (`cosim.simulation`) gives each recorded connector's unit and description and
the connections.  From them: the title names the scenario and the parameter sets applied;
each panel's y label carries its signals' units; a legend entry is the signal's name and a
description (a block's generic "Step output" says little, so such a signal is described by
the input it drives, e.g. "Set-point"); set-points (a controller's input ``r``, ``r1``, ...
and the signals driving it) are dashed.  `default_panels` chooses what to
show when the user names nothing: for each controller input pair ``r<k>``/``y<k>`` the
set-point with the controlled variable, then each controller's outputs ``u…``.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

_SETPOINT_INPUT = re.compile(r"r\d*")
_MEASUREMENT_INPUT = re.compile(r"y\d*")
_CONTROLLER_OUTPUT = re.compile(r"u\d*")


def connections(metadata: Mapping) -> list[tuple[str, str, bool]]:
    """(source, destination, identity) of each connection; identity: no factor or offset."""
    out = []
    for text in metadata.get("connections", []):
        src, _, rest = text.partition(" -> ")
        dst, _, transform = rest.partition(" ")
        out.append((src, dst, not transform))
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


def default_panels(metadata: Mapping, names: Sequence[str]) -> list[list[str]]:
    """Set-point with controlled variable for each controller loop, then each controller's
    outputs; every recorded output alone in its panel when no controller is found."""
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
    if loops:
        return loops + outputs
    driven = {src for src, _, _ in connections(metadata)}
    return [[n] for n in names if n in driven] or [[n] for n in names]


def title(metadata: Mapping, scenario: str) -> str:
    """``scenario — set1, set2`` (the parameter sets applied, by file stem)."""
    sets = [Path(p).stem for p in metadata.get("parameter_sets", [])]
    return scenario + (f" — {', '.join(sets)}" if sets else "")


def _ylabel(signals: Sequence[str], units: Mapping[str, str | None]) -> str:
    found = [u for u in dict.fromkeys(units.get(s) for s in signals) if u]
    return ", ".join(f"[{u}]" for u in found) if found else "value (no unit in the FMU)"


def plain(text: str) -> str:
    """``text`` as matplotlib shows it literally: every ``$`` escaped, so a name, description or
    unit holding ``$…$`` (or a lone ``$``) is never parsed as mathtext, which fails on what is
    not TeX."""
    return text.replace("$", r"\$")


def figure(result: np.ndarray, panels: Sequence[Sequence[str]], *, scenario: str, metadata: Mapping | None = None):
    """A matplotlib Figure: one subplot per panel, its signals overlaid against time (set-points
    dashed); labels, units and title from ``metadata`` (a run's JSON) as the module says, each
    shown literally (`plain`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metadata = metadata or {}
    units = metadata.get("units", {})
    dashed = setpoints(metadata, result.dtype.names)
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(9, 1.2 + 2.2 * len(panels)), squeeze=False)
    for ax, names in zip(axes[:, 0], panels):
        for name in names:
            ax.plot(result["time"], result[name], lw=1.3, ls="--" if name in dashed else "-",
                    label=plain(label(name, metadata)))
        ax.set_ylabel(plain(_ylabel(names, units)))
        ax.legend(loc="best", fontsize="small")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].set_title(plain(title(metadata, scenario)))
    fig.tight_layout()
    return fig


def plot(result: np.ndarray, panels: Sequence[Sequence[str]], path: str | Path, *, scenario: str,
         metadata: Mapping | None = None) -> Path:
    """`figure` written as an image (format from the suffix), through ``<path>.part`` and one
    rename (`cosim.safeio.atomic_path`): a reader never sees half a plot."""
    import matplotlib.pyplot as plt

    from .safeio import atomic_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = figure(result, panels, scenario=scenario, metadata=metadata)
    try:
        with atomic_path(path) as part:
            fig.savefig(part, dpi=110, format=path.suffix[1:] or "png")
    finally:
        plt.close(fig)
    return path
