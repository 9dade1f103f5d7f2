"""Parameter studies of the SOPDT predictive controller (Cîrtoaje et al., seed 001_*) and the ITAE-PID comparison.

    python docs/sopdt_report.py            # tables -> docs/sopdt_tables.md, figures -> docs/figures/sopdt_*.png

Every run goes through the master (``cosim.simulate``) on the scenarios ``ssp/sopdt_nominal``,
``ssp/sopdt_nmp`` and ``ssp/sopdt_pid_itae``, one system-level ``.ssv`` per case.  Metrics:
``cosim.present.metrics.step_metrics`` on the setpoint step (40 s … 2500 s, band ±2 %), IAE of the
load response (2500 s … 5000 s).  Stability is decided exactly, not from the plot: the loop is
linear, so ``spectral_radius`` builds the closed-loop map over one sampling period T from
the controller's own functions (free response (9)-(10), law weights) and the exact ZOH
discretisation of the test process with its dead time plus the master step (the controller's
output reaches the plant one master step after the sample), and the loop is stable iff ρ < 1.
"""

from __future__ import annotations

import math
import sys
import tempfile
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

import cosim  # noqa: E402
from cosim.present.metrics import step_metrics  # noqa: E402
from greyfmu.control import HorizonWarning, SOPDTPredictive, dominant_time_constant, free_response  # noqa: E402
from greyfmu.control.scheduling import ITAE  # noqa: E402
from greyfmu.plants import ThirdOrderPlant  # noqa: E402
from figure_files import save_figure  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
NOMINAL, NMP, PID_LOOP = (ROOT / "ssp" / name for name in ("sopdt_nominal", "sopdt_nmp", "sopdt_pid_itae"))
FIGURES = ROOT / "docs" / "figures"
TABLES = ROOT / "docs" / "sopdt_tables.md"

MASTER_STEP = 2.0
"""The scenarios' step: the controller's output reaches the plant one step after its sample."""
SETPOINT_TIME, LOAD_TIME, STOP_TIME = 40.0, 2500.0, 5000.0
START = dict(K=1.2, T0=200.0, tau=90.0, Ts=40.0)
"""The paper's starting data (§3); the other tuning defaults are SOPDTPredictive's: the paper's."""

STUDIES = [
    # (name, what the paper shows, scenario, controller parameter, values, plant T4)
    ("xk", "Figs. 3-4: X_k", NOMINAL, "X_k", [1.0, 1.1, 1.2, 1.5, 2.0, 3.0, 4.0], 0.0),
    ("tref", "Fig. 5: reference trajectory T_ref (0 = none)", NOMINAL, "T_ref", [0.0, 100.0, 200.0, 400.0], 0.0),
    ("xd", "Figs. 6-8: X_d (m = [2.25 X_d] = 0 … 7)", NOMINAL, "X_d", [0.3, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.2], 0.0),
    ("xt", "Figs. 6-8: X_t", NOMINAL, "X_t", [0.3, 0.5, 0.8, 1.0, 1.5, 1.8, 2.0], 0.0),
    ("xi", "Fig. 9: xi", NOMINAL, "xi", [0.2, 0.4, 0.6, 0.8, 1.0], 0.0),
    ("xp", "Fig. 10: X_p", NOMINAL, "X_p", [0.2, 0.4, 0.6, 0.8, 1.0], 0.0),
    ("law", "laws (7), (12), (15) at X_k = 1.5", NOMINAL, "law", [7, 12, 15], 0.0),
    ("nmp", "Fig. 11: X_k on the NMP process (T4 = 60 s)", NMP, "X_k", [1.5, 2.0, 3.0, 4.0, 6.0, 10.0], 60.0),
]


# --- exact stability of the sampled loop ----------------------------------------------------------


def loop_matrix(tuning: dict, T4: float = 0.0, master_step: float = MASTER_STEP) -> np.ndarray:
    """Closed-loop map s_{k+1} = M s_k over one sampling period, setpoint 0, no limits.

    State: plant state x(kT), the applied inputs u_{k−1} … u_{k−L}, the outputs Y_{k−1}, Y_{k−2}.
    """
    controller = SOPDTPredictive(**{**START, **tuning})
    d, T = controller.design, controller.Ts
    plant = ThirdOrderPlant(T4=T4)
    delay_samples, fraction = divmod(plant.tau + master_step, T)
    delay_samples = int(delay_samples)
    Phi = plant.transition(T)[0]
    gamma_old = plant.transition(T - fraction)[0] @ plant.transition(fraction)[1]  # input u_{k−d−1} on [kT, kT+f)
    gamma_new = plant.transition(T - fraction)[1]  # input u_{k−d} on [kT+f, (k+1)T)
    L = max(d.m + 1, delay_samples + 2)
    size = 3 + L + 2

    def advance(s: np.ndarray) -> np.ndarray:
        x, u_past, Y1, Y2 = s[:3], s[3 : 3 + L], s[3 + L], s[4 + L]
        Y = plant.C @ x
        free = free_response(d, (Y2, Y1, Y), u_past)
        u = u_past[0] + controller.X_p * float(np.dot(controller.weights, controller.approach * Y - free[d.m :]))
        u_all = np.concatenate([[u], u_past])  # u_all[j] = u_{k−j}
        x_next = Phi @ x + gamma_old * u_all[delay_samples + 1] + gamma_new * u_all[delay_samples]
        return np.concatenate([x_next, u_all[:L], [Y, Y1]])

    return np.column_stack([advance(column) for column in np.eye(size)])


def spectral_radius(tuning: dict, T4: float = 0.0, master_step: float = MASTER_STEP) -> float:
    """Largest closed-loop eigenvalue modulus: the loop is asymptotically stable iff it is < 1."""
    return float(max(abs(np.linalg.eigvals(loop_matrix(tuning, T4, master_step)))))


def controller_radius(tuning: dict) -> float:
    """Spectral radius of the controller alone (measured output held at 0): u_t = u_{t−1} + X_p Σ q_i e_{t+i}
    with the free response driven only by its own past moves (10).  b ∝ X_k and q ∝ 1/X_k, so this map does
    not depend on X_k: a mode outside the unit circle here cannot be removed by raising X_k."""
    controller = SOPDTPredictive(**{**START, **tuning})
    d, L = controller.design, controller.design.m + 1

    def advance(u_past: np.ndarray) -> np.ndarray:
        free = free_response(d, (0.0, 0.0, 0.0), u_past)
        u = u_past[0] - controller.X_p * float(np.dot(controller.weights, free[d.m :]))
        return np.concatenate([[u], u_past[: L - 1]])

    matrix = np.column_stack([advance(column) for column in np.eye(L)])
    return float(max(abs(np.linalg.eigvals(matrix))))


def stability_limit(
    parameter: str, low: float, high: float, T4: float = 0.0, master_step: float = MASTER_STEP, **tuning
) -> float:
    """The value of ``parameter`` in [low, high] where ρ crosses 1 (ρ − 1 must change sign there)."""
    radius = lambda value: spectral_radius({**tuning, parameter: value}, T4, master_step) - 1.0  # noqa: E731
    return brentq(radius, low, high, xtol=1e-4)


def stable_intervals(parameter: str, grid: np.ndarray, T4: float = 0.0) -> list[tuple[float, float]]:
    """Maximal runs of the grid on which the loop is stable (grid resolution)."""
    stable = [spectral_radius({parameter: value}, T4) < 1.0 for value in grid]
    runs, start = [], None
    for i, (value, ok) in enumerate(zip(grid, stable)):
        if ok and start is None:
            start = value
        if not ok and start is not None:
            runs.append((start, grid[i - 1]))
            start = None
    if start is not None:
        runs.append((start, grid[-1]))
    return runs


def recovering_gain(tuning: dict, grid: np.ndarray = np.round(np.arange(1.5, 100.0001, 0.05), 4)) -> float:
    """The smallest X_k of ``grid`` (1.5 … 100) at which the loop with ``tuning`` is stable; NaN if none is."""
    for X_k in grid:
        if spectral_radius({**tuning, "X_k": float(X_k)}) < 1.0:
            return float(X_k)
    return math.nan


def transient_time(plant: ThirdOrderPlant, band: float = 0.05, step: float = 1.0, horizon: float = 3000.0) -> float:
    """T_r of the paper's §2: the time after which the unit-step response stays within ±band of its final value K."""
    times = np.arange(step, horizon + step / 2, step)
    y = np.array([plant.advance(t - step, step, 1.0) for t in times])
    outside = np.flatnonzero(np.abs(y - plant.K) > band * abs(plant.K))
    return float(times[outside[-1] + 1])


HORIZON_PERIODS = [20.0, 24.0, 28.0, 32.0, 34.0, 36.0, 40.0, 46.0, 50.0, 56.0, 64.0, 70.0, 80.0]
"""Sampling periods T (multiples of the 2-s master step) for the N study: N = [690/T] = 34 … 8."""
DOMINANT_TIME_CONSTANTS = [100.0, 150.0, 200.0, 250.0, 300.0]
"""T0 values of the T0 study at T = 40 s (200 s = the sum of the test process's time constants)."""
REMEDY_CASES = [{"X_d": 0.3}, {"X_d": 0.5}, {"X_t": 1.5}, {"X_t": 1.8}, {"X_t": 2.0}, {"X_t": 3.0},
                {"X_d": 3.12}, {"X_d": 3.6}, {"X_d": 4.5}]
"""Tunings that lose stability at the default X_k = 1.5 (the paper: raising X_k usually restores it)."""


def design_row(tuning: dict) -> tuple[SOPDTPredictive, float, float]:
    """Controller, ρ and the X_k below which stability is lost (NaN if ρ ≥ 1 at X_k = 1.5 and 20)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HorizonWarning)
        controller = SOPDTPredictive(**{**START, **tuning})
        rho = spectral_radius(tuning)
        low = spectral_radius({**tuning, "X_k": 0.5}) - 1.0
        high = spectral_radius({**tuning, "X_k": 20.0}) - 1.0
        limit = stability_limit("X_k", 0.5, 20.0, **tuning) if low > 0.0 > high else math.nan
    return controller, rho, limit


def sweep_cells(parameter: str, value: float, folder: Path) -> tuple[SOPDTPredictive, str]:
    """The controller for ``parameter = value`` and its row's cells from ρ on (stability, limit, master-run metrics);
    ``parameter`` is also the FMU's name of it."""
    controller, rho, limit = design_row({parameter: value})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HorizonWarning)
        m = loop_metrics(run(NOMINAL, {f"controller.{parameter}": value}, folder))
    return controller, (
        f"{rho:.4f} | {'yes' if rho < 1 else '**no**'} | {fmt(limit, 3)} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | "
        f"{fmt(m['settling_time'], 0)} | {fmt(m['load_IAE'])} |"
    )


def horizon_tables(folder: Path) -> list[str]:
    """N against the paper's rule (15 ≤ N ≤ 20), then T0 (with the (T_r − τ)/3 rule), then the X_k remedy."""
    lines = [
        "### N = [(τ + 3 T0)/T]: the paper's rule N in 15 … 20, at most 20 (T varied, T0 = 200 s, X_k = 1.5)",
        "",
        "| T s | N | m | unmodelled delay τ + 2 s − m·T | ρ | stable | X_k where stability is lost | IAE (setpoint) | overshoot % | settling time s | IAE (load) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for T in HORIZON_PERIODS:
        controller, cells = sweep_cells("Ts", T, folder)
        d = controller.design
        lines.append(f"| {T:g} | {d.N} | {d.m} | {START['tau'] + MASTER_STEP - d.m * T:g} s | {cells}")
    T_r = transient_time(ThirdOrderPlant())
    T0_rule = dominant_time_constant(T_r, 90.0)
    lines += [
        "",
        f"### T0 (T = 40 s, X_k = 1.5): T_r of the test process (±5 %) = {T_r:.0f} s, so the rule T0 ≈ (T_r − τ)/3 "
        f"gives {T0_rule:.1f} s; the sum of its time constants is 200 s",
        "",
        "| T0 s | N | ρ | stable | X_k where stability is lost | IAE (setpoint) | overshoot % | settling time s | IAE (load) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for T0 in sorted([*DOMINANT_TIME_CONSTANTS, round(T0_rule, 1)]):
        controller, cells = sweep_cells("T0", T0, folder)
        lines.append(f"| {T0:g} | {controller.design.N} | {cells}")
    lines += [
        "",
        "### Raising X_k to recover stability lost to X_d or X_t (paper §4)",
        "",
        "| tuning | m | ρ at X_k = 1.5 | smallest stabilising X_k (grid 0.05, ≤ 100) | ρ at X_k = 100 | controller alone ρ_c |",
        "|---|---|---|---|---|---|",
    ]
    for tuning in REMEDY_CASES:
        controller = SOPDTPredictive(**{**START, **tuning})
        label = ", ".join(f"{k} = {v:g}" for k, v in tuning.items())
        X_k = recovering_gain(tuning)
        lines.append(
            f"| {label} | {controller.design.m} | {spectral_radius(tuning):.4f} | {'none' if math.isnan(X_k) else f'{X_k:g}'} | "
            f"{spectral_radius({**tuning, 'X_k': 100.0}):.4f} | {controller_radius(tuning):.5f} |"
        )
    return lines + [""]


# --- issue 31: the reference trajectory, X_p in 0.5 … 0.8, the horizon-overlap rule --------------------

REFERENCE_TIME_CONSTANTS = [0.0, 20.0, 40.0, 80.0, 100.0, 150.0, 200.0, 400.0]
"""T_ref values of the Fig. 5 study (0 = none); the paper gives none, its Fig. 5 is lost."""
WEIGHTINGS = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
"""X_p grid of the "fix X_p in advance at 0.5 … 0.8" study."""
WEIGHTING_CASES = [("nominal", NOMINAL, 0.0, 1.2), ("nominal", NOMINAL, 0.0, 1.5), ("nominal", NOMINAL, 0.0, 2.0),
                   ("nominal", NOMINAL, 0.0, 3.0), ("NMP T4 = 60 s", NMP, 60.0, 2.0), ("NMP T4 = 60 s", NMP, 60.0, 4.0)]
"""(process, scenario, T4, X_k) of the X_p study."""
OVERLAP_HORIZONS = [6, 8, 10, 12, 13, 15, 17, 20, 24, 30]
"""Horizons N at T = 40 s with the model fixed (T0 = 200 s): N·T = 240 … 1200 s against T_r = 518 s."""


def sampled_loop(tuning: dict, T4: float = 0.0) -> np.ndarray:
    """The scenario's loop (setpoint 1 at 40 s, load −0.2 at 2500 s, master step 2 s) without the FMUs: the controller
    samples every T, its output reaches the plant one master step later, as in ``cosim.simulate`` (equal to the
    master's run to the last bit for the nominal tuning, tested).  For tunings the FMU does not expose (``N``)."""
    controller, plant = SOPDTPredictive(**{**START, **tuning}), ThirdOrderPlant(T4=T4)
    steps = int(round(STOP_TIME / MASTER_STEP))
    result = np.zeros(steps + 1, dtype=[("time", float), ("plant.y", float), ("setpoint.y", float)])
    result["time"] = np.arange(steps + 1) * MASTER_STEP
    result["setpoint.y"] = (result["time"] >= SETPOINT_TIME).astype(float)
    applied = 0.0
    per_sample = int(round(controller.Ts / MASTER_STEP))
    for k in range(steps):
        t = result["time"][k]
        new = controller.step(result["setpoint.y"][k], result["plant.y"][k]) if k % per_sample == 0 else None
        result["plant.y"][k + 1] = plant.advance(t, MASTER_STEP, applied, -0.2 if t >= LOAD_TIME else 0.0)
        applied = applied if new is None else new
    return result


def metric_cells(rho: float, m: dict) -> str:
    return (f"{rho:.4f} | {'yes' if rho < 1 else '**no**'} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | "
            f"{fmt(m['rise_time'], 0)} | {fmt(m['settling_time'], 0)} | {fmt(m['load_IAE'])} |")


def best_weighting(scenario: Path, T4: float, X_k: float, folder: Path) -> tuple[float, dict[float, float]]:
    """The X_p of ``WEIGHTINGS`` with the smallest setpoint IAE among the stable loops, and every stable IAE (master runs)."""
    iae = {X_p: loop_metrics(run(scenario, {"controller.X_k": X_k, "controller.X_p": X_p}, folder))["IAE"]
           for X_p in WEIGHTINGS if spectral_radius({"X_k": X_k, "X_p": X_p}, T4) < 1.0}
    return min(iae, key=iae.get), iae


def issue31_tables(folder: Path) -> list[str]:
    """Fig. 5's T_ref, the X_p range 0.5 … 0.8 against X_k and the process, and the horizon-overlap rule."""
    header = "| ρ | stable | IAE (setpoint) | overshoot % | rise time s | settling time s (±2 %) | IAE (load) |"
    rule = "|---|---|---|---|---|---|---|"
    lines = ["### Fig. 5: the reference trajectory's impact against T_ref (master runs; α^m = e^{−mT/T_ref}, m = 2)", "",
             "| T_ref s | α^m " + header, "|---|---" + rule]
    for T_ref in REFERENCE_TIME_CONSTANTS:
        m = loop_metrics(run(NOMINAL, {"controller.T_ref": T_ref}, folder))
        alpha_m = math.exp(-2 * START["Ts"] / T_ref) if T_ref else 0.0
        lines.append(f"| {T_ref:g} | {alpha_m:.3f} | {metric_cells(spectral_radius({'T_ref': T_ref}), m)}")
    lines += ["", "### §3: \"X_p can be fixed in advance at a value in the range 0.5 - 0.8\" (setpoint IAE, master runs; "
              "— = unstable)", "",
              "| process | X_k | " + " | ".join(f"X_p = {v:g}" for v in WEIGHTINGS) + " | best X_p | best in 0.5 … 0.8 against the best |",
              "|---|---|" + "---|" * len(WEIGHTINGS) + "---|---|"]
    for process, scenario, T4, X_k in WEIGHTING_CASES:
        best, iae = best_weighting(scenario, T4, X_k, folder)
        in_range = min(iae[v] for v in (0.5, 0.6, 0.7, 0.8) if v in iae)
        cells = " | ".join(fmt(iae[v]) if v in iae else "—" for v in WEIGHTINGS)
        lines.append(f"| {process} | {X_k:g} | {cells} | {best:g} | +{100 * (in_range / iae[best] - 1):.1f} % |")
    T_r = transient_time(ThirdOrderPlant())
    lines += ["", f"### §4/abstract: \"the prediction horizon should completely overlap the transient time\" (T = 40 s, "
              f"model fixed at T0 = 200 s, N set directly; T_r = {T_r:.0f} s; Python loop `sampled_loop`, the FMU has no N)", "",
              "| N | N·T s | N·T / T_r | X_k where stability is lost " + header, "|---|---|---|---" + rule]
    for N in OVERLAP_HORIZONS:
        _, rho, limit = design_row({"N": N})
        m = loop_metrics(sampled_loop({"N": N}))
        lines.append(f"| {N} | {N * START['Ts']:g} | {N * START['Ts'] / T_r:.2f} | {fmt(limit, 3)} | {metric_cells(rho, m)}")
    return lines + [""]


# --- runs through the master ---------------------------------------------------------------------------


def write_ssv(path: Path, values: dict[str, float | int]) -> Path:
    """A system-level parameter set (names ``component.variable``) for ``cosim.simulate``."""
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="case">',
        "  <ssv:Parameters>",
    ]
    for name, value in values.items():
        kind = "Integer" if isinstance(value, int) else "Real"
        lines.append(f'    <ssv:Parameter name="{name}"><ssv:{kind} value="{value!r}"/></ssv:Parameter>')
    lines += ["  </ssv:Parameters>", "</ssv:ParameterSet>", ""]
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def run(scenario: Path, values: dict[str, float | int], folder: Path) -> np.ndarray:
    ssv = write_ssv(folder / f"case{len(list(folder.iterdir()))}.ssv", values)
    return cosim.simulate(scenario, parameter_sets=[ssv])


def loop_metrics(result: np.ndarray) -> dict[str, float]:
    """Setpoint-step metrics (±2 % band) and the load response's IAE and peak deviation."""
    time, y, r = result["time"], result["plant.y"], result["setpoint.y"]
    metrics = step_metrics(time, y, r, t0=SETPOINT_TIME, t1=LOAD_TIME)
    after = time >= LOAD_TIME
    error = np.abs(r[after] - y[after])
    metrics["load_IAE"] = float(np.sum((error[1:] + error[:-1]) * np.diff(time[after])) / 2)
    metrics["load_peak"] = float(error.max())
    metrics["final_error"] = float(abs(r[-1] - y[-1]))
    return metrics


def fmt(value: float, digits: int = 1) -> str:
    if not math.isfinite(value):
        return "—"
    if abs(value) >= 1e4:
        return f"{value:.1e}"
    return f"{value:.{digits}f}"


def study_table(title: str, parameter: str, rows: list[tuple[float, float, dict]]) -> list[str]:
    lines = [
        f"### {title}",
        "",
        f"| {parameter} | ρ | stable | IAE (setpoint) | overshoot % | rise time s | settling time s (±2 %) | IAE (load) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for value, rho, m in rows:
        lines.append(
            f"| {value:g} | {rho:.4f} | {'yes' if rho < 1 else '**no**'} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | "
            f"{fmt(m['rise_time'], 0)} | {fmt(m['settling_time'], 0)} | {fmt(m['load_IAE'])} |"
        )
    return lines + [""]


def plot_study(name: str, title: str, cases: list[tuple[str, np.ndarray]]) -> None:
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for label, result in cases:
        time = result["time"]
        top.plot(time, result["plant.y"], label=label)
        bottom.plot(time, result["controller.u"])
    top.plot(cases[0][1]["time"], cases[0][1]["setpoint.y"], "k:", label="setpoint")
    top.set_ylim(-0.5, 2.5)
    bottom.set_ylim(-1.0, 4.0)
    top.set_ylabel("y")
    bottom.set_ylabel("u")
    bottom.set_xlabel("time [s]")
    top.set_title(f"SOPDT predictive control — {title}")
    top.legend(fontsize=8, loc="upper right")
    for axis in (top, bottom):
        axis.grid(True, alpha=0.3)
        axis.axvline(LOAD_TIME, color="grey", lw=0.5)
    figure.tight_layout()
    save_figure(figure, FIGURES / f"sopdt_{name}.png", dpi=110)
    plt.close(figure)


def plot_stability(curves: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    figure, axis = plt.subplots(figsize=(7, 4))
    for label, (grid, rho) in curves.items():
        axis.plot(grid, rho, label=label)
    axis.axhline(1.0, color="k", lw=0.8)
    axis.set_xlabel("X_k")
    axis.set_ylabel("closed-loop spectral radius ρ")
    axis.set_ylim(0.8, 1.3)
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=8)
    axis.set_title("Stability of the sampled loop against X_k (ρ < 1: stable)")
    figure.tight_layout()
    save_figure(figure, FIGURES / "sopdt_stability.png", dpi=110)
    plt.close(figure)


def main() -> int:
    FIGURES.mkdir(parents=True, exist_ok=True)
    lines = [
        "# SOPDT predictive control: measured parameter studies",
        "",
        "Generated by `python docs/sopdt_report.py` (do not edit). Setpoint step 0 → 1 at 40 s,",
        "load −0.2 on the plant input at 2500 s, master step 2 s; metrics of the setpoint step over",
        "40–2500 s (`cosim.present.metrics.step_metrics`, band ±2 %), IAE of the load response over 2500–5000 s.",
        "ρ: spectral radius of the exact sampled closed loop (stable iff ρ < 1).",
        "",
    ]
    with tempfile.TemporaryDirectory(prefix="sopdt-report-") as temp:
        folder = Path(temp)
        for name, title, scenario, parameter, values, T4 in STUDIES:
            cases, rows = [], []
            for value in values:
                result = run(scenario, {f"controller.{parameter}": value}, folder)
                rows.append((value, spectral_radius({parameter: value}, T4), loop_metrics(result)))
                cases.append((f"{parameter} = {value:g}", result))
            lines += study_table(title, parameter, rows)
            plot_study(name, title, cases)
            print(f"{name}: done", file=sys.stderr)

        grid = np.round(np.arange(0.6, 12.0001, 0.05), 4)
        curves = {
            "law (7), T4 = 0": (grid, np.array([spectral_radius({"X_k": v}) for v in grid])),
            "law (12), T4 = 0": (grid, np.array([spectral_radius({"X_k": v, "law": 12}) for v in grid])),
            "law (15), T4 = 0": (grid, np.array([spectral_radius({"X_k": v, "law": 15}) for v in grid])),
            "law (7), T4 = 60 s": (grid, np.array([spectral_radius({"X_k": v}, 60.0) for v in grid])),
        }
        plot_stability(curves)
        limits = [
            ("law (7), T4 = 0, X_p = 0.6", stability_limit("X_k", 0.8, 1.5)),
            ("law (7), T4 = 0, X_p = 0.6, no master-step delay", stability_limit("X_k", 0.8, 1.5, master_step=0.0)),
            ("law (7), T4 = 0, X_p = 1", stability_limit("X_k", 0.8, 2.0, X_p=1.0)),
            ("law (7), T4 = 60 s, X_p = 0.6", stability_limit("X_k", 1.5, 3.0, T4=60.0)),
        ]
        for law in (12, 15):
            for X_p in (0.2, 0.4, 0.6):
                if spectral_radius({"X_k": 20.0, "law": law, "X_p": X_p}) < 1.0:
                    limits.append((f"law ({law}), T4 = 0, X_p = {X_p}", stability_limit("X_k", 0.8, 20.0, law=law, X_p=X_p)))
                else:
                    limits.append((f"law ({law}), T4 = 0, X_p = {X_p}", math.nan))
        lines += ["### X_k at which stability is lost (ρ = 1; stable above, up to X_k = 20 at least)", ""]
        lines += ["| loop | X_k |", "|---|---|"]
        lines += [f"| {label} | {'none ≤ 20' if math.isnan(value) else f'{value:.3f}'} |" for label, value in limits] + [""]
        fine = np.round(np.arange(0.1, 4.0001, 0.01), 4)
        lines += ["### Stable ranges at X_k = 1.5 (grid step 0.01)", "", "| parameter | stable for |", "|---|---|"]
        for parameter in ("X_d", "X_t"):
            runs = stable_intervals(parameter, fine)
            lines.append(f"| {parameter} | {', '.join(f'{a:g} … {b:g}' for a, b in runs)} |")
        lines.append("")
        lines += horizon_tables(folder)
        print("horizon: done", file=sys.stderr)
        lines += issue31_tables(folder)
        print("issue 31: done", file=sys.stderr)

        itae, detuned = ITAE()(1.2, 200.0, 90.0), ITAE(A=0.35)(1.2, 200.0, 90.0)
        comparison = [
            ("SOPDT predictive, law (7), starting data", run(NOMINAL, {}, folder)),
            ("SOPDT predictive, X_k = 2", run(NOMINAL, {"controller.X_k": 2.0}, folder)),
            (f"PID, ITAE (2.8) A = 0.35: Kc = {detuned.Kc:.3f}, Ti = {detuned.Ti:.1f} s, Td = {detuned.Td:.1f} s", run(PID_LOOP, {}, folder)),
            (f"PID, ITAE (2.8) A = 1.357: Kc = {itae.Kc:.3f}", run(PID_LOOP, {"controller.Kc": itae.Kc}, folder)),
        ]
    lines += [
        "### Against the foundation's PID tuned by ITAE (2.8) for K = 1.2, T = 200 s, τ = 90 s",
        "",
        "| controller | IAE (setpoint) | overshoot % | rise time s | settling time s | IAE (load) | peak load deviation | final error |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, result in comparison:
        m = loop_metrics(result)
        lines.append(
            f"| {label} | {fmt(m['IAE'])} | {fmt(m['overshoot'])} | {fmt(m['rise_time'], 0)} | {fmt(m['settling_time'], 0)} | "
            f"{fmt(m['load_IAE'])} | {fmt(m['load_peak'], 3)} | {fmt(m['final_error'], 4)} |"
        )
    lines.append("")
    plot_study("pid_itae", "predictive vs ITAE PID", [(label.split(":")[0], result) for label, result in comparison[:3]])
    TABLES.write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {TABLES} and {FIGURES}/sopdt_*.png", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
