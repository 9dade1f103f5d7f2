"""Tables and figures of the OSMM-GPC issue (Pan, Shen & Luh 2012, seed 003, §5).

    python docs/osmm_report.py     # tables -> docs/osmm_tables.md, figures -> docs/figures/osmm_*.png

Every run goes through the master (``cosim.simulate``): ``ssp/osmm_mfrls`` (Table 2) and
``ssp/osmm_header`` with no set (OSMM-GPC), ``gpc_12.ssv`` and ``gpc_13.ssv`` (Table 3).
Header metrics per valve step (2050 s and 3500 s) and pressure: the largest deviation from
8.75 MPa until the next step ("overshoot", MPa) and the settling time, the last instant the
pressure is outside ±0.02 MPa before the next step, minus the step time.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cosim  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"
TABLES = ROOT / "docs" / "osmm_tables.md"
PAPER_TABLE2 = {"global_frls": (0.0523, 0.0260), "local_frls": (0.0236, 0.0204), "mfrls": (0.0174, 0.0126)}
PAPER_TABLE3 = {"gpc_12": 40525.0, "gpc_13": 40475.0, "osmm": 39825.0}
LABELS = {"gpc_12": "GPC with boilers 1 and 2", "gpc_13": "GPC with boilers 1 and 3", "osmm": "OSMM-GPC"}
SETS = {"gpc_12": ["ssp/osmm_header/gpc_12.ssv"], "gpc_13": ["ssp/osmm_header/gpc_13.ssv"], "osmm": []}
STEPS = ((2050.0, 3500.0), (3500.0, 4500.0))
BAND = 0.02


def deviation_metrics(t: np.ndarray, y: np.ndarray, start: float, end: float) -> tuple[float, float]:
    window = (t >= start) & (t < end)
    error = y[window] - 8.75
    outside = np.flatnonzero(np.abs(error) > BAND)
    settling = t[window][outside[-1]] - start if len(outside) else 0.0
    return float(np.max(np.abs(error))), float(settling)


def main() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    lines = ["# OSMM-GPC: tables produced by docs/osmm_report.py", ""]
    run = cosim.simulate(str(ROOT / "ssp/osmm_mfrls"), stop_time=1500, step_size=1.0)
    lines += ["## Table 2: MAE (43) of the on-line estimated TS model (four-tank, §5.1)", "",
              "| estimator | paper h1 | paper h2 | ours h1 | ours h2 |", "|---|---|---|---|---|"]
    for name, (p1, p2) in PAPER_TABLE2.items():
        lines.append(f"| {name} | {p1} | {p2} | {run[name + '.mae1'][-1]:.4f} | {run[name + '.mae2'][-1]:.4f} |")
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for j, ax in enumerate(axes, start=1):
        ax.plot(run["time"], run[f"plant.h{j}"], "k", lw=1, label=f"h{j} (plant)")
        for name in PAPER_TABLE2:
            ax.plot(run["time"], run[f"{name}.y_hat{j}"], lw=0.7, label=name)
        ax.set_ylabel(f"h{j}")
        ax.legend(fontsize=7)
    axes[-1].set_xlabel("step k")
    fig.savefig(FIGURES / "osmm_mfrls.png", dpi=110)
    plt.close(fig)

    runs = {name: cosim.simulate(str(ROOT / "ssp/osmm_header"), stop_time=4500, step_size=1.0,
                                 parameter_sets=[str(ROOT / s) for s in sets]) for name, sets in SETS.items()}
    lines += ["", "## Table 3: fuel over steps 2000–4500 and header-pressure metrics (§5.2)", "",
              "| control | paper fuel [kg/2500 s] | ours [kg/2500 s] | ours mean [kg/s] | P_m2 dev/settle 1st step | P_m4 dev/settle 1st step | P_m2 dev/settle 2nd step | P_m4 dev/settle 2nd step |",
              "|---|---|---|---|---|---|---|---|"]
    fuels = {}
    for name, r in runs.items():
        t = r["time"]
        window = t >= 2000
        fuels[name] = float(np.trapezoid(r["header.fuel"][window], t[window]))
        cells = []
        for start, end in STEPS:
            for y in ("header.y1", "header.y2"):
                dev, settle = deviation_metrics(t, r[y], start, end)
                cells.append(f"{dev:.3f} MPa / {settle:.0f} s")
        lines.append(f"| {LABELS[name]} | {PAPER_TABLE3[name]:.0f} | {fuels[name]:.0f} | {fuels[name] / 2500:.3f} | " + " | ".join(cells) + " |")
    for other in ("gpc_12", "gpc_13"):
        saving = 100 * (fuels[other] - fuels["osmm"]) / fuels[other]
        paper = 100 * (PAPER_TABLE3[other] - PAPER_TABLE3["osmm"]) / PAPER_TABLE3[other]
        lines.append(f"\nOSMM-GPC vs {LABELS[other]}: saving {saving:+.2f} % (paper {paper:+.2f} %)")
    group = runs["osmm"]["controller.active_group"]
    t = runs["osmm"]["time"]
    changes = t[1:][np.diff(group) != 0]
    names = {1: "(1,2)", 2: "(1,3)", 3: "(2,3)"}
    lines.append("\nOSMM-GPC group switches (time s → group): " + ", ".join(
        f"{c:.0f} → {names[int(group[np.searchsorted(t, c)])]}" for c in changes))
    TABLES.write_text("\n".join(lines) + "\n")

    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for name, r in runs.items():
        axes[0].plot(r["time"], r["header.y1"], lw=0.8, label=LABELS[name])
        axes[1].plot(r["time"], r["header.y2"], lw=0.8, label=LABELS[name])
        axes[2].plot(r["time"], r["header.fuel"], lw=0.8, label=LABELS[name])
    for i in (1, 2, 3):
        axes[3].plot(runs["osmm"]["time"], runs["osmm"][f"controller.u{i}"], lw=0.8, label=f"OSMM M{i}")
    for ax, label in zip(axes, ("P_m2 [MPa]", "P_m4 [MPa]", "fuel [kg/s]", "firing [p.u.]")):
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    axes[-1].set_xlim(1900, 4500)
    axes[-1].set_xlabel("time [s]")
    fig.savefig(FIGURES / "osmm_header.png", dpi=110)
    plt.close(fig)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
