"""The sweep's summary figure, ``sweep.png`` beside ``sweep.csv``: each step metric against each
swept parameter (a row of panels per metric, a column per parameter; with one parameter, the
metrics in a grid of up to three columns), each y label the metric, its signal and its unit
(`cosim.present.metrics.metric_unit`).  At each value of the parameter the dots are every completed
run there (the other parameters and the seeds as spread), the line joins their medians and,
where some value has more than one run, the band spans their minimum to maximum."""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from collections.abc import Mapping
from typing import Any

from ..present.metrics import metric_unit
from ..safeio import atomic_path


def metric_label(column: str, units: Mapping[str, str | None]) -> str:
    """``overshoot of plant.y [%]`` for the column ``plant.y:overshoot``."""
    signal, _, metric = column.rpartition(":")
    unit = metric_unit(metric, units.get(signal))
    return f"{metric} of {signal}" + (f" [{unit}]" if unit else "")


def _grid(metrics: int, swept: int) -> tuple[int, int]:
    """(rows, columns): a row per metric and a column per parameter, or with one parameter the
    metrics in rows of up to three."""
    if swept > 1:
        return metrics, swept
    columns = min(3, metrics)
    return math.ceil(metrics / columns), columns


def summary_figure(rows: Sequence[dict[str, Any]], swept: Sequence[str], metrics: Sequence[str],
                   path: Path, title: str, units: Mapping[str, str | None] | None = None) -> Path | None:
    """Write `draw`'s figure to ``path``; None (no figure) without metrics or completed runs."""
    import matplotlib.pyplot as plt

    fig = draw(rows, swept, metrics, title, units)
    if fig is None:
        return None
    try:
        with atomic_path(path) as part:
            fig.savefig(part, dpi=110, format=Path(path).suffix[1:])
    finally:
        plt.close(fig)
    return path


def draw(rows: Sequence[dict[str, Any]], swept: Sequence[str], metrics: Sequence[str], title: str,
         units: Mapping[str, str | None] | None = None):
    """The figure (a matplotlib Figure) from the table's rows (``units``: each signal's unit, as
    `cosim.present.plots.units` resolves it); None without metrics or completed runs."""
    done = [r for r in rows if r["status"] == "completed"]
    if not metrics or not swept or not done:
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    units = units or {}
    nrows, ncols = _grid(len(metrics), len(swept))
    fig, grid = plt.subplots(nrows, ncols, figsize=(3.6 * ncols + 0.8, 2.3 * nrows), squeeze=False)
    flat = [ax for row in grid for ax in row]
    for ax in flat[len(metrics) * len(swept):]:
        ax.set_visible(False)
    repeated = False
    for j, name in enumerate(swept):
        levels = sorted({r[name] for r in done})
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in levels)
        where = {v: (float(v) if numeric else k) for k, v in enumerate(levels)}
        for i, metric in enumerate(metrics):
            ax = grid[i][j] if len(swept) > 1 else flat[i]
            xs, values = [], []
            for v in levels:
                ys = [r[metric] for r in done if r[name] == v and r[metric] is not None and math.isfinite(r[metric])]
                ax.plot([where[v]] * len(ys), ys, ".", color="0.55", markersize=4)
                if ys:
                    xs.append(where[v])
                    values.append(ys)
            if any(len(y) > 1 for y in values):
                repeated = True
                ax.fill_between(xs, [min(y) for y in values], [max(y) for y in values], alpha=0.2, color="C0")
            if xs:
                ax.plot(xs, [float(np.median(y)) for y in values], "-o", color="C0", markersize=3)
            if not numeric:
                ax.set_xticks(range(len(levels)), [str(v) for v in levels])
            if j == 0 or len(swept) == 1:
                ax.set_ylabel(metric_label(metric, units), fontsize=8)
            ax.set_xlabel(name, fontsize=8)
            ax.grid(True, alpha=0.3)
    what = "median, min-max band, every run" if repeated else "one run per value"
    fig.suptitle(f"{title}: {len(done)} completed runs ({what})", fontsize=9)
    fig.tight_layout()
    return fig
