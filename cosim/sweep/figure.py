"""The sweep's summary figure, ``sweep.png`` beside ``sweep.csv``: each step metric against each
swept parameter (a row of panels per metric, a column per parameter).  At each value of the
parameter the dots are every completed run there (the other parameters and the seeds as
spread), the line joins their medians and the band spans their minimum to maximum."""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..safeio import atomic_path


def summary_figure(rows: Sequence[dict[str, Any]], swept: Sequence[str], metrics: Sequence[str],
                   path: Path, title: str) -> Path | None:
    """Draw the figure from the table's rows; None (no figure) without metrics or completed runs."""
    done = [r for r in rows if r["status"] == "completed"]
    if not metrics or not swept or not done:
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(len(metrics), len(swept), figsize=(3.6 * len(swept) + 0.8, 2.3 * len(metrics)),
                             squeeze=False, sharex="col")
    for j, name in enumerate(swept):
        levels = sorted({r[name] for r in done})
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in levels)
        where = {v: (float(v) if numeric else k) for k, v in enumerate(levels)}
        for i, metric in enumerate(metrics):
            ax = axes[i][j]
            xs, values = [], []
            for v in levels:
                ys = [r[metric] for r in done if r[name] == v and r[metric] is not None and math.isfinite(r[metric])]
                ax.plot([where[v]] * len(ys), ys, ".", color="0.55", markersize=4)
                if ys:
                    xs.append(where[v])
                    values.append(ys)
            if xs:
                ax.fill_between(xs, [min(y) for y in values], [max(y) for y in values], alpha=0.2, color="C0")
                ax.plot(xs, [float(np.median(y)) for y in values], "-o", color="C0", markersize=3)
            if not numeric:
                ax.set_xticks(range(len(levels)), [str(v) for v in levels])
            if j == 0:
                ax.set_ylabel(metric, fontsize=8)
            if i == len(metrics) - 1:
                ax.set_xlabel(name)
            ax.grid(True, alpha=0.3)
    fig.suptitle(f"{title}: {len(done)} completed runs (median, min-max band, every run)", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as part:
        fig.savefig(part, dpi=110, format=Path(path).suffix[1:])
    plt.close(fig)
    return path
