"""What a tuning leaves a user to act on: ``best.ssv`` (the best parameters, an SSP 1.0
parameter set ``cosim run --param-set`` takes), ``convergence.png`` (every evaluation's
objective and the best so far, and where each parameter went) and the HTML summary that
heads the best run's report (``tune.html``: `cosim.present.report.render` with it in front)."""
from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Sequence
from pathlib import Path

from ..model.structure import ParameterValue
from ..sweep.values import write_ssv
from .evaluations import Evaluation, Objective
from .space import SearchSpace


def write_best(path: Path, space: SearchSpace, best: Evaluation, name: str) -> Path:
    """``best``'s values as an SSP 1.0 parameter set (names ``component.variable``)."""
    write_ssv(path, [ParameterValue(p.name, p.type, best.values[p.name], "cosim tune", 0) for p in space.parameters],
              name=name)
    return path


def convergence_figure(evaluations: Sequence[Evaluation], space: SearchSpace, objective: Objective, title: str):
    """A matplotlib Figure: the objective of each evaluation (feasible, infeasible; failed or
    unmeasured ones as ticks on the top edge) with the best feasible so far, then one panel per
    parameter with its value at each evaluation and the best point's."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from ..present.plots import plain

    n = len(space.parameters)
    fig, axes = plt.subplots(1 + n, 1, figsize=(8, 3 + 1.4 * n), sharex=True,
                             gridspec_kw={"height_ratios": [3] + [1] * n})
    ax = axes[0]
    index = np.array([ev.index for ev in evaluations])
    values = np.array([ev.value for ev in evaluations])
    feasible = np.array([ev.feasible for ev in evaluations])
    finite = np.isfinite(values)
    ax.plot(index[finite & feasible], values[finite & feasible], ".", ms=4, color="#1f77b4", label="feasible")
    if (finite & ~feasible).any():
        ax.plot(index[finite & ~feasible], values[finite & ~feasible], "x", ms=4, color="#ff7f0e",
                label="violates a constraint")
    best, so_far = math.inf, []
    for ev in evaluations:
        if ev.feasible and ev.value < best:
            best = ev.value
        so_far.append(best)
    so_far = np.array(so_far)
    shown = np.isfinite(so_far)
    ax.step(index[shown], so_far[shown], where="post", color="black", lw=1.2, label="best so far")
    if finite.any() and values[finite].min() > 0 and values[finite].max() > 100 * values[finite].min():
        ax.set_yscale("log")
    if (~finite).any():
        ax.plot(index[~finite], np.full((~finite).sum(), 1.0), "|", ms=10, color="#d62728",
                transform=ax.get_xaxis_transform(), clip_on=False, label="failed or unmeasured")
    ax.set_ylabel(plain(objective.describe()))
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(plain(title))
    ax.grid(True, alpha=0.3)
    best_ev = min((ev for ev in evaluations if ev.feasible), key=lambda ev: ev.value, default=None)
    for p, pax in zip(space.parameters, axes[1:]):
        pax.plot(index, [ev.values[p.name] for ev in evaluations], ".", ms=3, color="0.4")
        if best_ev is not None:
            pax.axhline(best_ev.values[p.name], color="#2ca02c", lw=1)
        if p.scale == "log":
            pax.set_yscale("log")
        pax.set_ylim(p.low, p.high)
        pax.set_ylabel(plain(p.name), fontsize=8)
        pax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("evaluation")
    fig.tight_layout()
    return fig


def write_convergence(path: Path, evaluations: Sequence[Evaluation], space: SearchSpace, objective: Objective,
                      title: str) -> tuple[Path, bytes]:
    """``convergence.png``, and its bytes (for the report)."""
    import matplotlib.pyplot as plt

    from ..safeio import write_atomic

    fig = convergence_figure(evaluations, space, objective, title)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    write_atomic(path, buffer.getvalue())
    return path, buffer.getvalue()


def _cell(value: object) -> str:
    if isinstance(value, float):
        return "–" if value != value else f"{value:.6g}"
    return html.escape("–" if value is None else str(value))


def summary(*, scenario: str, method: str, message: str, space: SearchSpace, objective: Objective,
            evaluations: Sequence[Evaluation], best: Evaluation | None, seeds: Sequence[int], png: bytes,
            command: str, seconds: float) -> str:
    """The tuning's section of the report (HTML)."""
    failed = [ev for ev in evaluations if ev.status != "completed"]
    replayed = sum(ev.replayed for ev in evaluations)
    rows = "".join(f"<tr><td class=t>{html.escape(p.name)}</td><td>{p.low:g} … {p.high:g}</td><td class=t>{p.scale}"
                   f"</td><td>{_cell(v)}</td><td><b>{_cell(best.values[p.name]) if best else '–'}</b></td></tr>"
                   for p, v in zip(space.parameters, space.current))
    measures = [(name if w == 1 else f"{w:g} × {name}", "objective term",
                 best.terms.get(name) if best else None) for name, w in objective.weights]
    measures += [(c.text(), "constraint (worst seed)" if len(seeds) > 1 else "constraint",
                  best.constraints.get(c.text()) if best else None) for c in objective.constraints]
    outcome = "".join(f"<tr><td class=t>{html.escape(n)}</td><td class=t>{k}</td><td>{_cell(v)}</td></tr>"
                      for n, k, v in measures)
    failures = "".join(f"<tr><td>{ev.index}</td><td class=t>{html.escape(ev.status)}</td>"
                       f"<td class=t>{html.escape(ev.error or '')}</td><td class=t>{html.escape(ev.message or '')}</td></tr>"
                       for ev in failed[:20])
    verdict = ("no evaluation completed" if best is None else
               f"best objective <b>{best.value:.6g}</b> at evaluation {best.index}"
               + ("" if best.feasible else " (<b>no evaluation met the constraints</b>: the one closest to them)"))
    seed_text = f"averaged over {len(seeds)} noise seeds ({', '.join(map(str, seeds))})" if seeds else "one run each"
    return f"""<h2>Tuning</h2>
<p>{html.escape(scenario)}: {html.escape(method)}, {len(evaluations)} evaluations ({replayed} from an earlier tuning's
table), {seed_text}, {len(failed)} failed or unmeasured; {verdict}. {html.escape(message)} ({seconds:.3g} s.)</p>
<p>Run the best parameters: <code>{html.escape(command)}</code></p>
<table><tr><th>parameter</th><th>bounds</th><th>scale</th><th>scenario's value</th><th>best</th></tr>{rows}</table>
<table><tr><th>objective / constraint</th><th></th><th>at the best</th></tr>{outcome}</table>
<img alt="convergence" src="data:image/png;base64,{base64.b64encode(png).decode('ascii')}">
{f'<h3>Failed or unmeasured evaluations (first 20 of {len(failed)})</h3><table><tr><th>#</th><th>status</th><th>error</th><th>message</th></tr>{failures}</table>' if failed else ''}
<h2>The best run</h2>
"""
