"""Sensitivity of the thesis's three grey-PI claims (ch. 4) to a_min, the bias B, the LDISPI spacing m and the threshold.

    python docs/btg_sensitivity_report.py        # 60 settings, about fifteen minutes on one core

Every run is ssp/btg_boiler_following through cosim with the thesis's fuel controllers (``thesis.ssv``:
no anti-windup, no output limits) and one grey-PI setting written to a temporary parameter set.  The
figures of merit, one per claim of §4.2 (grey PI against the PI of the same form):

- **S, stability on fast ramps** (Sim. 4.2 CASES 5 and 8, 1500 s): the grey PI settles (last 300 s within
  2 kgf/cm² and 2 MW) in both, where the PI does not;
- **D, smaller disturbance error with less fuel action** (the 26 % / 600 s / 300 s fuel pulse of Sim. 4.3
  CASE 1 and Sim. 4.4, noise-free, first period): peak pressure error ≤ 0.8 × the PI's and fuel-command
  range < the PI's;
- **N, equal noise sensitivity** (Sim. 4.4 CASE 1, white noise 0.2 / 2 s, first period): standard
  deviation of the noise-induced fuel command (noisy minus noise-free run) within 0.8-1.2 × the PI's.

Writes docs/btg_sensitivity_tables.md and docs/figures/btg_sensitivity.png (heat-map of the claims held).
"""

from __future__ import annotations

import itertools
import tempfile
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
TABLES = ROOT / "docs" / "btg_sensitivity_tables.md"
FIGURE = ROOT / "docs" / "figures" / "btg_sensitivity.png"
THRESHOLDS = {1: "a > a_min", 2: "|a| > a_min"}
CELLS = {k: v.replace("|", "\\|") for k, v in THRESHOLDS.items()}
"""The threshold names as markdown table cells."""
A_MIN = (0.0, 0.005, 0.01, 0.02, 0.035)
BIAS = (25.0, 50.0, 100.0)
SPACING = (1, 5)
RAMPS = ("sim42_case5", "sim42_case8")
RAMP_STOP = 1500.0
PULSE = "sim44_case1"
PULSE_STOP = 700.0
"""One pulse period (100-700 s) of the 600 s pulse: enough for the peak error, the fuel range and the noise."""
DISTURBANCE_RATIO, NOISE_BAND = 0.8, (0.8, 1.2)


@dataclass(frozen=True)
class Setting:
    threshold: int
    a_min: float
    B: float
    m: int

    def parameter_set(self, folder: Path) -> Path:
        """This setting as an SSV file for the fuel_grey component."""
        path = folder / f"grey_t{self.threshold}_a{self.a_min}_B{self.B}_m{self.m}.ssv"
        values = (("threshold", "Integer", self.threshold), ("a_min", "Real", self.a_min),
                  ("B", "Real", self.B), ("m", "Integer", self.m))
        rows = "\n".join(f'    <ssv:Parameter name="fuel_grey.{name}"><ssv:{kind} value="{value}"/></ssv:Parameter>'
                         for name, kind, value in values)
        path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/'
                        'SSP1/SystemStructureParameterValues" version="1.0" name="setting">\n  <ssv:Parameters>\n'
                        f"{rows}\n  </ssv:Parameters>\n</ssv:ParameterSet>\n")
        return path


THESIS_SETTING = Setting(1, 0.035, 50.0, 5)
"""§4.2 as printed: a > 0.035, B = 50 kgf/cm², LDISPI m = 5 (Simulation 3.6)."""


def run(case: str, controller: str, stop: float, *extra: Path, noise: bool = True) -> np.ndarray:
    sets = [SCENARIO / f"{case}.ssv", SCENARIO / f"{controller}.ssv", SCENARIO / "thesis.ssv", *extra]
    if not noise:
        sets.append(SCENARIO / "noise_free.ssv")
    return cosim.simulate(SCENARIO, stop_time=stop, step_size=0.5, parameter_sets=sets)


def settles(r: np.ndarray) -> bool:
    tail = r["time"] >= r["time"][-1] - 300.0
    e_p, e_e = r["pressure_sp.y"] - r["plant.P"], r["demand.y"] - r["plant.E"]
    return bool(np.all(np.isfinite(e_p)) and np.max(np.abs(e_p[tail])) < 2.0 and np.max(np.abs(e_e[tail])) < 2.0)


def pulse_merits(noisy: np.ndarray, clean: np.ndarray, fuel: str) -> tuple[float, float, float]:
    """Peak pressure error and fuel-command range of the noise-free run; std of the noise-induced command."""
    peak = float(np.max(np.abs(clean["pressure_sp.y"] - clean["plant.P"])))
    return peak, float(np.ptp(np.clip(clean[fuel], 0.0, 100.0))), float(np.std(noisy[fuel] - clean[fuel]))


def merits(setting: Setting | None, folder: Path) -> dict[str, float | bool]:
    """The figures of merit of one grey setting (None: the PI of the thesis's form)."""
    controller, fuel = ("pi", "fuel_pi.u") if setting is None else ("grey", "fuel_grey.u")
    extra = () if setting is None else (setting.parameter_set(folder),)
    ramps = [run(case, controller, RAMP_STOP, *extra) for case in RAMPS]
    noisy, clean = run(PULSE, controller, PULSE_STOP, *extra), run(PULSE, controller, PULSE_STOP, *extra, noise=False)
    peak, fuel_range, noise = pulse_merits(noisy, clean, fuel)
    out: dict[str, float | bool] = {f"settles_{case}": settles(r) for case, r in zip(RAMPS, ramps)}
    out.update(peak=peak, fuel_range=fuel_range, noise=noise,
               predicted=float(np.mean(ramps[1]["fuel_grey.mode"] == 2)) if setting else float("nan"))
    return out


def claims(grey: dict, pi: dict) -> dict[str, bool]:
    """Which of the three claims hold for this grey setting against the PI."""
    stable = all(grey[f"settles_{c}"] for c in RAMPS) and not all(pi[f"settles_{c}"] for c in RAMPS)
    disturbance = grey["peak"] <= DISTURBANCE_RATIO * pi["peak"] and grey["fuel_range"] < pi["fuel_range"]
    low, high = NOISE_BAND
    return {"S": stable, "D": disturbance, "N": low <= grey["noise"] / pi["noise"] <= high}


def heat_map(results: dict[Setting, tuple[dict, dict]]) -> None:
    fig, axes = plt.subplots(len(THRESHOLDS), len(SPACING), figsize=(10, 7), sharex=True, sharey=True)
    for (row, threshold), (col, m) in itertools.product(enumerate(THRESHOLDS), enumerate(SPACING)):
        ax = axes[row, col]
        grid = np.zeros((len(A_MIN), len(BIAS)))
        for (i, a_min), (j, B) in itertools.product(enumerate(A_MIN), enumerate(BIAS)):
            _, held = results[Setting(threshold, a_min, B, m)]
            grid[i, j] = sum(held.values())
            label = "".join(k if v else "·" for k, v in held.items())
            ax.text(j, i, label, ha="center", va="center", fontsize=10, family="monospace")
        image = ax.imshow(grid, vmin=0, vmax=3, cmap="RdYlGn", origin="lower", aspect="auto")
        ax.set_title(f"{THRESHOLDS[threshold]}, m = {m}", fontsize=10)
        ax.set_xticks(range(len(BIAS)), [f"{b:g}" for b in BIAS])
        ax.set_yticks(range(len(A_MIN)), [f"{a:g}" for a in A_MIN])
        if row == len(THRESHOLDS) - 1:
            ax.set_xlabel("bias B [kgf/cm²]")
        if col == 0:
            ax.set_ylabel("a_min")
    fig.colorbar(image, ax=axes, label="claims held (S stable on ramps, D disturbance, N noise)")
    fig.suptitle("Grey PI vs PI, thesis's PI form (no anti-windup): which of the three ch. 4 claims hold")
    save_figure(fig, FIGURE, dpi=80)
    plt.close(fig)


def fmt(value: float | bool) -> str:
    return ("yes" if value else "no") if isinstance(value, bool) else f"{value:.3g}"


def main() -> None:
    settings = [Setting(*s) for s in itertools.product(THRESHOLDS, A_MIN, BIAS, SPACING)]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        pi = merits(None, folder)
        print("PI", pi, flush=True)
        results = {}
        for setting in settings:
            grey = merits(setting, folder)
            results[setting] = (grey, claims(grey, pi))
            print(setting, grey, results[setting][1], flush=True)
    heat_map(results)
    head = ("| threshold | a_min | B | m | settles CASE 5 | settles CASE 8 | predicting % (CASE 8) | peak e_P / PI "
            "| fuel range / PI | noise std / PI | S | D | N |\n|" + "---|" * 13 + "\n")
    lines = [f"| {CELLS[s.threshold]} | {s.a_min:g} | {s.B:g} | {s.m} | {fmt(g['settles_sim42_case5'])} "
             f"| {fmt(g['settles_sim42_case8'])} | {100 * g['predicted']:.1f} | {g['peak'] / pi['peak']:.2f} "
             f"| {g['fuel_range'] / pi['fuel_range']:.2f} | {g['noise'] / pi['noise']:.2f} | "
             + " | ".join("**yes**" if held[k] else "no" for k in "SDN") + " |"
             for s, (g, held) in results.items()]
    every = [s for s, (_, held) in results.items() if all(held.values())]
    TABLES.write_text(
        "# Grey PI sensitivity study, thesis ch. 4 (generated by docs/btg_sensitivity_report.py)\n\n"
        f"PI of the thesis's form (thesis.ssv): settles CASE 5 {fmt(pi['settles_sim42_case5'])}, CASE 8 "
        f"{fmt(pi['settles_sim42_case8'])}; pulse peak e_P {pi['peak']:.2f} kgf/cm², fuel range "
        f"{pi['fuel_range']:.1f} %, noise std {pi['noise']:.3f} %.  Claims: S = the grey PI settles in CASES 5 "
        f"and 8 (and the PI does not in at least one), D = peak e_P <= {DISTURBANCE_RATIO} x PI's and a smaller fuel "
        f"range, N = noise std within {NOISE_BAND[0]}-{NOISE_BAND[1]} x PI's.  Thesis setting: "
        f"{THRESHOLDS[THESIS_SETTING.threshold]} = {THESIS_SETTING.a_min}, B = {THESIS_SETTING.B:g}, m = "
        f"{THESIS_SETTING.m}.\n\nSettings where all three hold: "
        + (", ".join(f"({THRESHOLDS[s.threshold]}, a_min {s.a_min:g}, B {s.B:g}, m {s.m})" for s in every) or "none")
        + ".\n\n" + head + "\n".join(lines) + "\n")
    print(TABLES.read_text())


if __name__ == "__main__":
    main()
