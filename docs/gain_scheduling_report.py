"""Regenerate the gain-scheduling tables and figures of docs/gain_scheduling.md (thesis §2.3, Simulations 2.1-2.5).

    python docs/gain_scheduling_report.py

Runs every scenario ssp/gs_sim2_* variant through cosim (about two minutes), writes
docs/gain_scheduling_tables.md (one table per simulation) and docs/figures/gs_*.png.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cosim  # noqa: E402
from cosim.present.metrics import step_metrics  # noqa: E402
from figure_files import save_figure  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SSP = ROOT / "ssp"
FIGURES = ROOT / "docs" / "figures"
TABLES = ROOT / "docs" / "gain_scheduling_tables.md"
CONTROLLERS = ("itae", "mfgs", "fgs1", "fgs2")
COMPARISONS = {
    "gs_sim2_3": "Simulation 2.3 — process gain Kp(y) varies (Figures 2.3, 2.4), integral mode (2.12)",
    "gs_sim2_4": "Simulation 2.4 — time constant T(y) varies (Figures 2.5–2.9), integral mode (2.10)",
    "gs_sim2_5": "Simulation 2.5 — dead time τ(y) varies (Figures 2.10–2.14), integral mode (2.12)",
}
MODE_STUDIES = {
    "gs_sim2_1": ("Simulation 2.1 — process gain varies, integral modes (Figure 2.1)", {
        "step_low": ("step_low",),
        "step_low, D on e": ("step_low", "derivative_error"),
        "step_up": ("step_up",),
        "step_up, D on e": ("step_up", "derivative_error"),
        "reversed: Kp falls along the step 0.5 → 4": ("kp_falling",),
    }, 300.0),
    "gs_sim2_2": ("Simulation 2.2 — dead time varies, integral modes (Figure 2.2)", {
        "step_up": ("step_up",),
        "step_down": ("step_down",),
        "reversed: τ falls in y, step_up": ("step_up", "tau_falling"),
        "reversed: τ falls in y, step_down": ("step_down", "tau_falling"),
        "T(y) rises in y (τ = 4 s), step_up": ("step_up", "t_rising"),
        "T(y) rises in y (τ = 4 s), step_down": ("step_down", "t_rising"),
        "T(y) falls in y (τ = 4 s), step_up": ("step_up", "t_falling"),
        "T(y) falls in y (τ = 4 s), step_down": ("step_down", "t_falling"),
    }, 600.0),
}
"""Per study: title, variants (label: parameter sets, each combined with one integral mode), stop time.
"D on e" = the thesis's derivative on the error (derivative_error.ssv); ours differentiates the measurement."""


def simulate(folder: str, *sets: str, stop_time: float) -> np.ndarray:
    return cosim.simulate(SSP / folder, stop_time=stop_time, parameter_sets=[SSP / folder / f"{s}.ssv" for s in sets])


def window_iae(result: np.ndarray, start: float, end: float) -> float:
    t = result["time"]
    keep = (t >= start) & (t <= end)
    e = np.abs(result["setpoint.y"][keep] - result["plant.y"][keep])
    return float(np.sum((e[1:] + e[:-1]) * np.diff(t[keep])) / 2)


def fmt(value: float, digits: int = 1) -> str:
    return "—" if not np.isfinite(value) else f"{value:.{digits}f}"


def comparison(folder: str, title: str) -> list[str]:
    lines = [f"## {title}", "", "Set-point 1 → 4 at 10 s (metrics over 10–400 s, settling band ±2 %); load step +d at "
             "400 s (IAE over 400–800 s) and back to 0 at 800 s (IAE over 800–1200 s).", "",
             "| case | controller | IAE | overshoot % | settling s | rise s | IAE +d | IAE −d |",
             "|---|---|---|---|---|---|---|---|"]
    for case in (1, 2, 3):
        fig, ax = plt.subplots(figsize=(8, 4))
        for law in CONTROLLERS:
            result = simulate(folder, f"case{case}", law, stop_time=1200.0)
            m = step_metrics(result["time"], result["plant.y"], result["setpoint.y"], t0=10.0, t1=400.0)
            lines.append(
                f"| {case} | {law.upper()} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | {fmt(m['settling_time'])} | "
                f"{fmt(m['rise_time'])} | {fmt(window_iae(result, 400, 800), 2)} | {fmt(window_iae(result, 800, 1200), 2)} |"
            )
            ax.plot(result["time"], result["plant.y"], label=law.upper())
        ax.plot(result["time"], result["setpoint.y"], "k:", label="set-point")
        ax.set(xlabel="time [s]", ylabel="y", title=f"{title.split(' —')[0]} CASE {case}")
        ax.legend()
        fig.tight_layout()
        save_figure(fig, FIGURES / f"gs_{folder[3:]}_case{case}.png", dpi=100)
        plt.close(fig)
    return lines + [""]


def mode_study(folder: str, title: str, variants: dict[str, tuple[str, ...]], stop: float) -> list[str]:
    lines = [f"## {title}", "", "| variant | integral mode | IAE | overshoot % | settling s | rise s |",
             "|---|---|---|---|---|---|"]
    fig, axes = plt.subplots(1, len(variants), figsize=(4 * len(variants), 4))
    for ax, (label, sets) in zip(axes, variants.items()):
        for mode, eq in ((1, "(2.10)"), (2, "(2.11)"), (3, "(2.12)")):
            result = simulate(folder, *sets, f"mode{mode}", stop_time=stop)
            m = step_metrics(result["time"], result["plant.y"], result["setpoint.y"], t0=10.0)
            lines.append(f"| {label} | {eq} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | {fmt(m['settling_time'])} | "
                         f"{fmt(m['rise_time'])} |")
            ax.plot(result["time"], result["plant.y"], label=eq)
        ax.plot(result["time"], result["setpoint.y"], "k:", label="set-point")
        ax.set(xlabel="time [s]", ylabel="y")
        ax.set_title(label, fontsize=9)
        ax.legend()
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, FIGURES / f"gs_{folder[3:]}.png", dpi=80)
    plt.close(fig)
    return lines + [""]


def derivative_forms(folder: str, title: str) -> list[str]:
    """The set-point response with our derivative (on the measurement) and the thesis's (on the error)."""
    lines = [f"## {title}: derivative on the measurement (ours) and on the error (thesis, derivative_error.ssv)", "",
             "| case | controller | overshoot % (ours / D on e) | rise s | settling s |", "|---|---|---|---|---|"]
    for case in (1, 2, 3):
        for law in CONTROLLERS:
            m = [setpoint_response(folder, f"case{case}", law, *extra) for extra in ((), ("derivative_error",))]
            lines.append(f"| {case} | {law.upper()} | {fmt(m[0]['overshoot'])} / {fmt(m[1]['overshoot'])} | "
                         f"{fmt(m[0]['rise_time'])} / {fmt(m[1]['rise_time'])} | "
                         f"{fmt(m[0]['settling_time'])} / {fmt(m[1]['settling_time'])} |")
    return lines + [""]


DIRECTIONS = {"1 → 4": (False, False), "4 → 1": (False, True), "mirrored, 1 → 4": (True, False),
              "mirrored, 4 → 1": (True, True)}
"""The four directions of the paragraphs after each CASE 3: (mirrored p(7.76 - y), set-point step down)."""


def direction_sets(folder: str, case: int, mirrored: bool, down: bool) -> list[str]:
    sets = [f"mirrored_case{case}" if mirrored else f"case{case}"]
    if down:
        sets.append("down" if folder != "gs_sim2_3" else f"{'mirrored_' if mirrored else ''}down_case{case}")
    return sets


def directions(folder: str, title: str) -> list[str]:
    """Set-point responses in the four directions (down_*.ssv, mirrored_*.ssv)."""
    lines = [f"## {title.split(' (')[0]}: the reversed directions (set-point steps, metrics over 10–400 s)", "",
             "| case | direction | controller | IAE | overshoot % | settling s | rise s |", "|---|---|---|---|---|---|---|"]
    for case in (1, 2, 3):
        for label, (mirrored, down) in DIRECTIONS.items():
            for law in CONTROLLERS:
                m = setpoint_response(folder, *direction_sets(folder, case, mirrored, down), law)
                lines.append(f"| {case} | {label} | {law.upper()} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | "
                             f"{fmt(m['settling_time'])} | {fmt(m['rise_time'])} |")
    return lines + [""]


def setpoint_response(folder: str, *sets: str) -> dict[str, float]:
    result = simulate(folder, *sets, stop_time=400.0)
    return step_metrics(result["time"], result["plant.y"], result["setpoint.y"], t0=10.0)


def main() -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    lines = ["# Gain scheduling: measured tables", "", "Generated by `python docs/gain_scheduling_report.py`; "
             "see docs/gain_scheduling.md for what the chapter concludes and what we see.", ""]
    for folder, (title, variants, stop) in MODE_STUDIES.items():
        lines += mode_study(folder, title, variants, stop)
    for folder, title in COMPARISONS.items():
        lines += comparison(folder, title)
    for folder, title in COMPARISONS.items():
        lines += directions(folder, title)
    lines += derivative_forms("gs_sim2_4", "Simulation 2.4")
    TABLES.write_text("\n".join(lines))
    print(f"wrote {TABLES} and {FIGURES}/gs_*.png")


if __name__ == "__main__":
    main()
