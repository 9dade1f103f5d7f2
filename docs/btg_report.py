"""Regenerate the tables and figures of docs/btg.md: thesis 000_*, ch. 4, Figures 4.2/4.3, Simulations 4.1-4.4.

    python docs/btg_report.py            # every case (about fifteen minutes on one core)
    python docs/btg_report.py sim43      # only the cases whose name starts with sim43 (tables not written)

Runs ssp/btg_boiler_following (Figure 4.1) through cosim once per case and controller form:

- ``PI ours`` / ``grey ours``: our controllers (conditional-integration anti-windup, outputs limited to
  0-100 %, the grey PI predicting when |a| > a_min);
- ``PI thesis`` / ``grey thesis``: the thesis's fuel controllers as printed (``thesis.ssv``: no anti-windup,
  no output limits, the valve clips; the grey PI predicting when a > a_min);
- ``grey thesis |a|``: the thesis's PI form with our |a| rule (``thesis.ssv`` + ``magnitude.ssv``).

For the noisy pulse cases each form also runs without noise, to isolate the noise's share of the fuel
command.  Writes docs/btg_tables.md and docs/figures/btg_*.png, and times one 3000 s load-following run
(Simulation 4.2 CASE 8) at the scenario's step.
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
from figure_files import save_figure  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "ssp" / "btg_boiler_following"
FIGURES = ROOT / "docs" / "figures"
TABLES = ROOT / "docs" / "btg_tables.md"
OUTPUT = {"pi": "fuel_pi.u", "grey": "fuel_grey.u"}
NOISE_FREE = SCENARIO / "noise_free.ssv"
THESIS = SCENARIO / "thesis.ssv"
MAGNITUDE = SCENARIO / "magnitude.ssv"
FORMS: dict[str, tuple[str, tuple[Path, ...]]] = {
    "PI ours": ("pi", ()),
    "grey ours": ("grey", ()),
    "PI thesis": ("pi", (THESIS,)),
    "grey thesis": ("grey", (THESIS,)),
    "grey thesis |a|": ("grey", (THESIS, MAGNITUDE)),
}
LEVEL_SETPOINT_MM = 100.0
"""The thesis's -100 mm drum-level set-point in the model's datum (scenario README)."""
LEVEL_STEADY_MM, LEVEL_TRANSIENT_MM = 50.0, 100.0
"""§4.2's drum-level criterion: within ±50 mm at a steady load demand, short excursions within ±100 mm."""


@dataclass(frozen=True)
class Case:
    name: str
    title: str
    stop: float
    step: float
    """Master step: 0.5 s (all sample times 0.5/1 s) unless the noise is sampled every 0.1 s."""
    period: float | None = None
    """Period of the fuel pulse [s] (Sim. 4.3/4.4); None for a set-point or load change."""


CASES = (
    [Case(f"fig42_{d}", f"Fig. 4.2, unit load-demand step {d} at 76 MW", 800.0, 0.5) for d in ("up", "down")]
    + [Case(f"fig43_{d}", f"Fig. 4.3, unit pressure set-point step {d} at 76 MW", 800.0, 0.5) for d in ("up", "down")]
    + [Case(f"sim41_{n}", f"Sim. 4.1, unit pressure set-point step at {n} MW", 800.0, 0.5) for n in (58, 76, 101)]
    + [Case(f"sim42_case{c}", f"Sim. 4.2 CASE {c}", 1500.0, 0.5) for c in range(1, 11)]
    + [Case(f"sim43_case{c}", f"Sim. 4.3 CASE {c}", 1900.0, 0.1, 400.0 if c == 2 else 600.0) for c in (1, 2, 3)]
    + [Case(f"sim44_case{c}", f"Sim. 4.4 CASE {c}", 1900.0, 0.1 if c == 3 else 0.5, 600.0) for c in range(1, 6)]
)
SAME_RUN = {"sim44_case3": "sim43_case1"}
"""Sim. 4.4 CASE 3 is Sim. 4.3 CASE 1 (same pulse, same noise): its rows are copied, not re-run."""
SETTLE_WINDOW = 300.0
"""Seconds at the end of a run in which a non-periodic case must have settled."""
SETTLE_P, SETTLE_E = 2.0, 2.0
"""Settled: |pressure error| < 2 kgf/cm2 and |power error| < 2 MW over the window (noise std is < 0.5)."""
BOUND = 50.0
"""Bounded: |pressure error| < 50 kgf/cm2 and |power error| < 50 MW throughout."""
CHANGE_AT = 100.0
"""Every case changes its set-point, load demand or disturbance at t = 100 s."""


def simulate(case: str, form: str, *, stop: float, step: float, noise: bool = True) -> np.ndarray:
    controller, extra = FORMS[form]
    sets = [SCENARIO / f"{case}.ssv", SCENARIO / f"{controller}.ssv", *extra]
    if not noise:
        sets.append(NOISE_FREE)
    return cosim.simulate(SCENARIO, stop_time=stop, step_size=step, parameter_sets=sets)


def integral(t: np.ndarray, y: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2)


def overshoot(t: np.ndarray, y: np.ndarray, setpoint: np.ndarray) -> float:
    """Largest excursion of y beyond the final set-point, in the direction of the set-point change, in % of
    that change (0 = none); NaN if the set-point does not change."""
    change = setpoint[-1] - setpoint[0]
    if abs(change) < 1e-9:
        return float("nan")
    beyond = np.sign(change) * (y[t >= CHANGE_AT] - setpoint[-1])
    return float(max(0.0, 100 * np.max(beyond) / abs(change)))


def metrics(result: np.ndarray, controller: str, period: float | None) -> dict[str, float | bool]:
    """The report's columns for one run (errors on the true pressure and power, not the noisy measurement)."""
    t = result["time"]
    e_p = result["pressure_sp.y"] - result["plant.P"]
    e_e = result["demand.y"] - result["plant.E"]
    level = result["plant.L"] - LEVEL_SETPOINT_MM
    u = result[OUTPUT[controller]]
    finite = bool(np.all(np.isfinite(e_p)) and np.all(np.isfinite(e_e)))
    bounded = finite and float(np.max(np.abs(e_p))) < BOUND and float(np.max(np.abs(e_e))) < BOUND
    tail = t >= t[-1] - SETTLE_WINDOW
    if period is not None:  # the response to the last disturbance period is no larger than to the first
        first = np.abs(e_p[(t >= CHANGE_AT) & (t < CHANGE_AT + period)]).max()
        last = np.abs(e_p[t >= t[-1] - period]).max()
        settled = bool(last <= 1.1 * first)
    else:
        settled = bool(np.max(np.abs(e_p[tail])) < SETTLE_P and np.max(np.abs(e_e[tail])) < SETTLE_E)
    return {
        "max_ep": float(np.max(np.abs(e_p))),
        "tail_ep": float(np.max(np.abs(e_p[tail]))),
        "iae_p": integral(t, np.abs(e_p)),
        "iae_e": integral(t, np.abs(e_e)),
        "os_p": overshoot(t, result["plant.P"], result["pressure_sp.y"]),
        "os_e": overshoot(t, result["plant.E"], result["demand.y"]),
        "level_max": float(np.max(np.abs(level))),
        "level_tail": float(np.max(np.abs(level[tail]))),
        "tv_u": float(np.sum(np.abs(np.diff(u)))),
        "u_range": float(np.ptp(np.clip(u, 0.0, 100.0))),
        "predicted": float(np.mean(result["fuel_grey.mode"] == 2)) if controller == "grey" else float("nan"),
        "stable": bounded and settled,
        "bounded": bounded,
        "settled": settled,
    }


def noise_std(noisy: np.ndarray, clean: np.ndarray, controller: str) -> float:
    """Standard deviation of the fuel command's noise-induced part: the same run with and without noise."""
    return float(np.std(noisy[OUTPUT[controller]] - clean[OUTPUT[controller]]))


def figure(case: Case, runs: dict[str, np.ndarray]) -> None:
    fig, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
    for form, r in runs.items():
        controller = FORMS[form][0]
        style = "--" if controller == "grey" else "-"
        axes[0].plot(r["time"], r["plant.P"], style, lw=1, label=form)
        axes[1].plot(r["time"], r["plant.E"], style, lw=1, label=form)
        axes[2].plot(r["time"], np.clip(r[OUTPUT[controller]], -10, 110), style, lw=1, label=form)
        axes[3].plot(r["time"], np.clip(r["plant.L"] - LEVEL_SETPOINT_MM, -400, 400), style, lw=1, label=form)
    r = runs["PI ours"]
    axes[0].plot(r["time"], r["pressure_sp.y"], ":k", label="set-point")
    axes[1].plot(r["time"], r["demand.y"], ":k", label="load demand")
    for limit in (-LEVEL_TRANSIENT_MM, LEVEL_TRANSIENT_MM):
        axes[3].axhline(limit, color="0.6", ls=":")
    for ax, label in zip(axes, ("pressure [kgf/cm²]", "power [MW]", "fuel command [%]", "level − set-point [mm]")):
        ax.set_ylabel(label)
        ax.grid(True)
    axes[0].legend(fontsize=7, loc="best", ncol=2)
    axes[0].set_title(f"{case.title} — ssp/btg_boiler_following")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    save_figure(fig, FIGURES / f"btg_{case.name}.png", dpi=80)
    plt.close(fig)


def fmt(value: float | bool, digits: int = 2) -> str:
    if isinstance(value, bool):
        return "yes" if value else "**no**"
    return "—" if not np.isfinite(value) else f"{value:.{digits}f}"


COLUMNS = (
    ("max \\|e_P\\|", "max_ep", 2), ("last 300 s \\|e_P\\|", "tail_ep", 2), ("IAE P", "iae_p", 0),
    ("IAE E", "iae_e", 0), ("overshoot P %", "os_p", 1), ("overshoot E %", "os_e", 1),
    ("level max mm", "level_max", 0), ("level last 300 s mm", "level_tail", 0), ("TV u", "tv_u", 0),
    ("u range %", "u_range", 1), ("noise std u", "noise_std", 3), ("grey predicting %", "predicted", 1),
    ("bounded", "bounded", 0), ("settled", "settled", 0),
)


def table(rows: list[tuple[Case, str, dict]]) -> str:
    head = "| case | fuel ctrl | " + " | ".join(c[0] for c in COLUMNS) + " |\n|" + "---|" * (len(COLUMNS) + 2) + "\n"
    lines = []
    for case, form, m in rows:
        cells = [fmt(100 * m[key] if key == "predicted" else m.get(key, float("nan")), digits)
                 for _, key, digits in COLUMNS]
        label = form.replace("|", "\\|")  # a table cell
        lines.append(f"| {case.name} | {label} | " + " | ".join(cells) + " |")
    return head + "\n".join(lines) + "\n"


def timed_load_following() -> tuple[float, float]:
    """Wall time of a 3000 s Simulation 4.2 CASE 8 run (PI and grey PI, ours) at the scenario's step."""
    times = []
    for controller in ("pi", "grey"):
        started = time.perf_counter()
        cosim.simulate(SCENARIO, stop_time=3000.0,
                       parameter_sets=[SCENARIO / "sim42_case8.ssv", SCENARIO / f"{controller}.ssv"])
        times.append(time.perf_counter() - started)
    return times[0], times[1]


def main(prefix: str = "") -> None:
    FIGURES.mkdir(parents=True, exist_ok=True)
    rows: list[tuple[Case, str, dict]] = []
    done: dict[str, list[tuple[str, dict]]] = {}
    for case in CASES:
        if not case.name.startswith(prefix):
            continue
        if case.name in SAME_RUN and SAME_RUN[case.name] in done:
            rows += [(case, form, m) for form, m in done[SAME_RUN[case.name]]]
            continue
        runs = {form: simulate(case.name, form, stop=case.stop, step=case.step) for form in FORMS}
        done[case.name] = []
        for form, result in runs.items():
            controller = FORMS[form][0]
            m = metrics(result, controller, case.period)
            if case.period is not None:
                clean = simulate(case.name, form, stop=case.stop, step=case.step, noise=False)
                m["noise_std"] = noise_std(result, clean, controller)
            rows.append((case, form, m))
            done[case.name].append((form, m))
            print(case.name, form, {k: round(v, 3) if isinstance(v, float) else v for k, v in m.items()}, flush=True)
        figure(case, runs)
    text = ("# Boiler-turbine-generator: PI vs grey predictive PI (generated by docs/btg_report.py)\n\n"
            "Errors are set-point minus the true (noise-free) pressure P / power E; overshoots in % of the set-point "
            "or load-demand change (— if none changes); level = drum level minus its set-point [mm] (§4.2's "
            "criterion: 50 mm steady, 100 mm in transients); u is the fuel controller's output [%], its range "
            "clipped to the valve's 0-100 %; 'noise std u' is the standard deviation of u(noisy run) - u(same run "
            "without noise); 'grey predicting' is the share of samples in which the grey PI acted on a 25 s "
            "prediction. Forms: 'ours' = anti-windup, outputs 0-100 %, |a| > a_min; 'thesis' = no anti-windup, "
            "no output limits, a > a_min (thesis.ssv); 'thesis |a|' = thesis.ssv + magnitude.ssv. Stable = bounded "
            "and settled (pulse cases: the last period's peak error within 110 % of the first's).\n\n"
            + table(rows))
    if not prefix:
        pi_time, grey_time = timed_load_following()
        text += (f"\nPerformance: 3000 s of Sim. 4.2 CASE 8 through cosim with all 14 FMUs, Gauss-Seidel, step 0.5 s: "
                 f"{pi_time:.1f} s wall (PI), {grey_time:.1f} s (grey PI).\n")
        TABLES.write_text(text)
    print(text)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "")
