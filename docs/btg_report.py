"""Regenerate the tables and figures of docs/btg.md: thesis 000_*, ch. 4, Simulations 4.1-4.4.

    python docs/btg_report.py            # every case (about five minutes on one core)
    python docs/btg_report.py sim43      # only the cases whose name starts with sim43

Runs ssp/btg_boiler_following (Figure 4.1) through cosim once per case and fuel controller
(PI and grey predictive PI; for the noisy pulse cases also without noise, to isolate the
noise's share of the fuel command), writes docs/btg_tables.md and docs/figures/btg_*.png,
and times one 3000 s load-following run (Simulation 4.2 CASE 8) at the scenario's step.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cosim  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "ssp" / "btg_boiler_following"
FIGURES = ROOT / "docs" / "figures"
TABLES = ROOT / "docs" / "btg_tables.md"
CONTROLLERS = ("pi", "grey")
OUTPUT = {"pi": "fuel_pi.u", "grey": "fuel_grey.u"}
NOISE_FREE = SCENARIO / "noise_free.ssv"


@dataclass(frozen=True)
class Case:
    name: str
    title: str
    stop: float
    step: float
    """Master step: 0.5 s (all sample times 0.5/1 s) unless the noise is sampled every 0.1 s."""
    periodic: bool = False


CASES = (
    [Case(f"sim41_{n}", f"Sim. 4.1, unit pressure set-point step at {n} MW", 800.0, 0.5) for n in (58, 76, 101)]
    + [Case(f"sim42_case{c}", f"Sim. 4.2 CASE {c}", 1500.0, 0.5) for c in range(1, 11)]
    + [Case(f"sim43_case{c}", f"Sim. 4.3 CASE {c}", 1900.0, 0.1, True) for c in (1, 2, 3)]
    + [Case(f"sim44_case{c}", f"Sim. 4.4 CASE {c}", 1900.0, 0.1 if c == 3 else 0.5, True) for c in range(1, 6)]
)
SETTLE_WINDOW = 300.0
"""Seconds at the end of a run in which a non-periodic case must have settled."""
SETTLE_P, SETTLE_E = 2.0, 2.0
"""Settled: |pressure error| < 2 kgf/cm2 and |power error| < 2 MW over the window (noise std is < 0.5)."""
BOUND = 50.0
"""Bounded: |pressure error| < 50 kgf/cm2 and |power error| < 50 MW throughout."""


def simulate(case: str, controller: str, *, stop: float, step: float, extra: tuple[Path, ...] = ()) -> np.ndarray:
    sets = [SCENARIO / f"{case}.ssv", SCENARIO / f"{controller}.ssv", *extra]
    return cosim.simulate(SCENARIO, stop_time=stop, step_size=step, parameter_sets=sets)


def integral(t: np.ndarray, y: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2)


def metrics(result: np.ndarray, controller: str, periodic: bool) -> dict[str, float | bool]:
    """The report's columns for one run (errors on the true pressure and power, not the noisy measurement)."""
    t = result["time"]
    e_p = result["pressure_sp.y"] - result["plant.P"]
    e_e = result["demand.y"] - result["plant.E"]
    u = result[OUTPUT[controller]]
    finite = bool(np.all(np.isfinite(e_p)) and np.all(np.isfinite(e_e)))
    bounded = finite and float(np.max(np.abs(e_p))) < BOUND and float(np.max(np.abs(e_e))) < BOUND
    if periodic:  # the response to the last disturbance period is no larger than to the first
        period = 600.0 if t[-1] > 1500 else 400.0
        first = np.abs(e_p[(t >= 100) & (t < 100 + period)]).max()
        last = np.abs(e_p[t >= t[-1] - period]).max()
        settled = bool(last <= 1.1 * first)
    else:
        tail = t >= t[-1] - SETTLE_WINDOW
        settled = bool(np.max(np.abs(e_p[tail])) < SETTLE_P and np.max(np.abs(e_e[tail])) < SETTLE_E)
    return {
        "max_ep": float(np.max(np.abs(e_p))),
        "iae_p": integral(t, np.abs(e_p)),
        "iae_e": integral(t, np.abs(e_e)),
        "tv_u": float(np.sum(np.abs(np.diff(u)))),
        "std_u": float(np.std(u)),
        "u_range": float(np.ptp(u)),
        "overshoot": overshoot(result) if result["sp_step.y"][-1] != 0 else float("nan"),
        "predicted": float(np.mean(result["fuel_grey.mode"] == 2)) if controller == "grey" else float("nan"),
        "stable": bounded and settled,
        "bounded": bounded,
        "settled": settled,
    }


def overshoot(result: np.ndarray) -> float:
    """Overshoot [%] of the throttle pressure after the set-point step (Sim. 4.1)."""
    step = result["sp_step.y"][-1]
    start = result["plant.P"][0]
    return float(100 * (np.max((result["plant.P"] - start) / step) - 1))


def noise_std(noisy: np.ndarray, clean: np.ndarray, controller: str) -> float:
    """Standard deviation of the fuel command's noise-induced part: the same run with and without noise."""
    return float(np.std(noisy[OUTPUT[controller]] - clean[OUTPUT[controller]]))


def figure(case: Case, runs: dict[str, np.ndarray]) -> None:
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for controller, style in zip(CONTROLLERS, ("-", "--")):
        r = runs[controller]
        label = "PI" if controller == "pi" else "grey PI"
        axes[0].plot(r["time"], r["plant.P"], style, label=f"P, {label}")
        axes[1].plot(r["time"], r["plant.E"], style, label=f"E, {label}")
        axes[2].plot(r["time"], r[OUTPUT[controller]], style, label=f"fuel command, {label}")
    r = runs["pi"]
    axes[0].plot(r["time"], r["pressure_sp.y"], ":k", label="set-point")
    axes[1].plot(r["time"], r["demand.y"], ":k", label="load demand")
    axes[2].plot(r["time"], r["turbine.u"], "-", color="0.6", label="governor command (PI run)")
    for ax, unit in zip(axes, ("kgf/cm²", "MW", "%")):
        ax.set_ylabel(unit)
        ax.grid(True)
        ax.legend(fontsize=8, loc="best")
    axes[0].set_title(f"{case.title} — ssp/btg_boiler_following")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(FIGURES / f"btg_{case.name}.png", dpi=90)
    plt.close(fig)


def fmt(value: float | bool, digits: int = 2) -> str:
    if isinstance(value, bool):
        return "yes" if value else "**no**"
    return "—" if not np.isfinite(value) else f"{value:.{digits}f}"


def table(rows: list[tuple[Case, str, dict]]) -> str:
    head = ("| case | fuel ctrl | max \\|e_P\\| | IAE P | IAE E | TV u | std u | noise std u | overshoot % "
            "| grey predicting | bounded | settled |\n|" + "---|" * 12 + "\n")
    lines = [f"| {c.name} | {ctl} | {fmt(m['max_ep'])} | {fmt(m['iae_p'], 0)} | {fmt(m['iae_e'], 0)} "
             f"| {fmt(m['tv_u'], 0)} | {fmt(m['std_u'])} | {fmt(m.get('noise_std', float('nan')), 3)} "
             f"| {fmt(m['overshoot'], 1)} | {fmt(100 * m['predicted'], 1)} | {fmt(m['bounded'])} "
             f"| {fmt(m['settled'])} |" for c, ctl, m in rows]
    return head + "\n".join(lines) + "\n"


def timed_load_following() -> tuple[float, float]:
    """Wall time of a 3000 s Simulation 4.2 CASE 8 run (PI and grey PI) at the scenario's step."""
    times = []
    for controller in CONTROLLERS:
        started = time.perf_counter()
        cosim.simulate(SCENARIO, stop_time=3000.0,
                       parameter_sets=[SCENARIO / "sim42_case8.ssv", SCENARIO / f"{controller}.ssv"])
        times.append(time.perf_counter() - started)
    return times[0], times[1]


def main(prefix: str = "") -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in CASES:
        if not case.name.startswith(prefix):
            continue
        runs = {c: simulate(case.name, c, stop=case.stop, step=case.step) for c in CONTROLLERS}
        for controller in CONTROLLERS:
            m = metrics(runs[controller], controller, case.periodic)
            if case.periodic:
                clean = simulate(case.name, controller, stop=case.stop, step=case.step, extra=(NOISE_FREE,))
                m["noise_std"] = noise_std(runs[controller], clean, controller)
            rows.append((case, controller, m))
            print(case.name, controller, {k: round(v, 3) if isinstance(v, float) else v for k, v in m.items()},
                  flush=True)
        figure(case, runs)
    text = ("# Boiler-turbine-generator: PI vs grey predictive PI (generated by docs/btg_report.py)\n\n"
            "Errors are set-point minus the true (noise-free) pressure / power; u is the fuel controller's output "
            "[%]; 'noise std u' is the standard deviation of u(noisy run) - u(same run without noise); 'grey "
            "predicting' is the share of samples in which |a| > a_min, so the grey PI acted on a 25 s prediction.\n\n"
            + table(rows))
    if not prefix:
        pi_time, grey_time = timed_load_following()
        text += (f"\nPerformance: 3000 s of Sim. 4.2 CASE 8 through cosim with all 14 FMUs, Gauss-Seidel, step 0.5 s: "
                 f"{pi_time:.1f} s wall (PI), {grey_time:.1f} s (grey PI).\n")
        TABLES.write_text(text)
    print(text)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "")
