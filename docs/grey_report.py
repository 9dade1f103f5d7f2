"""Run the grey scenarios and write the figures docs/figures/grey_*.png and the numbers docs/grey.md quotes.

    python docs/grey_report.py

Figures: Simulation 3.2 (Figs. 3.2/3.3), 3.3 (Figs. 3.4-3.6), 3.4 (Figs. 3.7/3.8), 3.5-3.7
(Figs. 3.9-3.11), grey PI vs PI, Fig. 3.12's basic scheme, GM(3/t,1) identification.  Metrics from cosim.present.metrics.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.chdir(ROOT)

import cosim  # noqa: E402
from cosim.present.metrics import step_metrics  # noqa: E402
from greyfmu.grey import GM11  # noqa: E402
from figure_files import save_figure  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
E0 = [590.227, 615.369, 591.63, 651.777, 677.115, 699.87, 704.298, 695.565, 749.685, 816.966, 788.533, 799.5]


def save(figure: plt.Figure, name: str) -> None:
    figure.tight_layout()
    save_figure(figure, FIGURES / f"grey_{name}.png", dpi=110)
    plt.close(figure)
    print(f"wrote docs/figures/grey_{name}.png")


def simulation_3_2() -> None:
    figure, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    k = np.arange(1, 13)
    for ax, start in zip(axes, (0, 1)):
        model = GM11.fit(E0[start:start + 7])
        ax.plot(k, E0, "o-", label="e0 (data)")
        ax.plot(k[start:], model.predict(np.arange(1, 13 - start)), "s--", label="GM(1,1) estimate / prediction")
        ax.axvline(start + 7.5, color="grey", lw=0.8)
        ax.set_title(f"Simulation 3.2 window {start + 1}: a = {model.a:.4f}, b = {model.b:.4f}")
        ax.set_xlabel("k")
        ax.legend()
    save(figure, "sim32")


def prediction_figure(result: np.ndarray, name: str, title: str, horizon: float) -> None:
    t = result["time"]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    top.plot(t, result["process.y"], label="process output")
    top.plot(t, result["predictor.x_hat"], "--", label=f"grey prediction, {horizon:g} s")
    top.set_ylim(-0.2, 4.5)
    top.set_title(title)
    top.legend()
    bottom.plot(t, result["predictor.a"], label="a(i)")
    bottom.set_ylim(-0.3, 0.3)
    bottom.set_xlabel("t [s]")
    bottom.legend()
    save(figure, name)


def simulations_3_3_and_3_4() -> None:
    for ph, ssv in ((20, None), (30, "ph30.ssv"), (40, "ph40.ssv")):
        r = cosim.simulate("ssp/grey_sim33", parameter_sets=[f"ssp/grey_sim33/{ssv}"] if ssv else [])
        prediction_figure(r, f"sim33_ph{ph}", f"Simulation 3.3: 1/(40s+1), horizon {ph} s (Figs. 3.4-3.6)", ph)
    r = cosim.simulate("ssp/grey_sim34")
    prediction_figure(r, "sim34_case1", "Simulation 3.4 CASE 1: 1/((1+40s)(1+20s)), horizon 40 s (Fig. 3.7)", 40)
    r = cosim.simulate("ssp/grey_sim34", parameter_sets=["ssp/grey_sim34/case2.ssv"])
    prediction_figure(r, "sim34_case2", "Simulation 3.4 CASE 2: 1/(1400s²+30s+1), horizon 30 s (Fig. 3.8)", 30)


def simulations_3_5_to_3_7() -> None:
    r = cosim.simulate("ssp/grey_noise")
    t, y = r["time"], r["process.y"]
    figure, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    settled = t > 550
    for ax, (name, label) in zip(axes, (("grey_1s", "Ts = 1 s, n = 4 (Sim. 3.5, Fig. 3.9)"),
                                        ("grey_5s", "Ts = 5 s, n = 4 (Sim. 3.6, Fig. 3.10)"),
                                        ("ldispi", "LDISPI Ts = 1 s, n = 4, m = 5 (Sim. 3.7, Fig. 3.11)"))):
        spread = np.std(r[f"{name}.x_hat"][settled] - y[settled])
        ax.plot(t, r["measurement.y"], lw=0.6, label="noisy output")
        ax.plot(t, r[f"{name}.x_hat"], label=f"prediction 20 s (spread {spread:.3f})")
        ax.set_xlim(280, 800)
        ax.set_ylim(-0.5, 1.8)
        ax.set_title(label)
        ax.legend(loc="lower right")
        print(f"{name}: spread about the process output after 550 s = {spread:.4f}")
    print(f"measurement noise spread = {np.std(r['measurement.y'][settled] - y[settled]):.4f}")
    axes[-1].set_xlabel("t [s]")
    save(figure, "noise")


def grey_pi_versus_pi() -> None:
    r = cosim.simulate("ssp/grey_pi_vs_pi")
    t = r["time"]
    quiet = (t > 250) & (t < 400)
    print("| | IAE | overshoot % | rise time s | settling time (±5 %) s | std(u) 250-400 s | load IAE 400-700 s |")
    print("|---|---|---|---|---|---|---|")
    for label, controller, plant in (("PI", "pi", "pi_plant"), ("grey PI", "grey_pi", "grey_plant")):
        m = step_metrics(t, r[f"{plant}.y"], r["setpoint.y"], t0=20, t1=400, band=0.05)
        load = step_metrics(t, r[f"{plant}.y"], r["setpoint.y"], t0=400)
        print(f"| {label} | {m['IAE']:.2f} | {m['overshoot']:.1f} | {m['rise_time']:.1f} | {m['settling_time']:.1f} | "
              f"{np.std(r[f'{controller}.u'][quiet]):.4f} | {load['IAE']:.2f} |")
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    top.plot(t, r["setpoint.y"], "k:", label="set-point")
    top.plot(t, r["pi_plant.y"], label="PI")
    top.plot(t, r["grey_plant.y"], label="grey predictive PI")
    top.set_title("Grey predictive PI vs PI on 1/((1+30s)(1+5s)), Kc = 3, Ti = 30 s, noise (3.27c)")
    top.legend()
    bottom.plot(t, r["pi.u"], label="PI u")
    bottom.plot(t, r["grey_pi.u"], label="grey PI u")
    bottom.plot(t, r["grey_pi.e_hat"], lw=0.8, label="grey PI predicted error")
    bottom.set_xlabel("t [s]")
    bottom.legend()
    save(figure, "pi_vs_pi")


def figure_3_12() -> None:
    """Fig. 3.12 (PI on the predicted output) against the PI and the error-prediction grey PI of Fig. 3.14."""
    r = cosim.simulate("ssp/grey_fig312")
    t = r["time"]
    loops = (("PI", "pi", "pi_plant"), ("Fig. 3.12: PI on ŷ", "out_pi", "out_plant"),
             ("Fig. 3.14: grey PI", "grey_pi", "grey_plant"))
    print("| | IAE | overshoot % | rise time s | settling time (±2 %) s | load IAE 400-700 s |")
    print("|---|---|---|---|---|---|")
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    top.plot(t, r["setpoint.y"], "k:", label="set-point")
    for label, controller, plant in loops:
        m = step_metrics(t, r[f"{plant}.y"], r["setpoint.y"], t0=20, t1=400)
        load = step_metrics(t, r[f"{plant}.y"], r["setpoint.y"], t0=400)
        print(f"| {label} | {m['IAE']:.2f} | {m['overshoot']:.1f} | {m['rise_time']:.1f} | {m['settling_time']:.1f} | "
              f"{load['IAE']:.2f} |")
        top.plot(t, r[f"{plant}.y"], label=label)
        bottom.plot(t, r[f"{controller}.u"], label=f"{label}: u")
    top.plot(t, r["predictor.x_hat"], lw=0.8, label="ŷ, 10 s ahead (Fig. 3.12)")
    top.set_title("Fig. 3.12 basic grey predictive control vs PI vs Fig. 3.14, 1/((1+30s)(1+5s)), Kc = 3, Ti = 30 s")
    top.legend(fontsize=8)
    bottom.set_xlabel("t [s]")
    bottom.legend(fontsize=8)
    save(figure, "fig312")


def gm3t1_identification() -> None:
    figure, ax = plt.subplots(figsize=(9, 3.8))
    for ssv, label in ((None, "k_s = 2, ω_n = 0.1, ζ = 0.5"), ("overdamped.ssv", "k_s = 0.5, ω_n = 0.05, ζ = 2")):
        r = cosim.simulate("ssp/grey_gm3t1", parameter_sets=[f"ssp/grey_gm3t1/{ssv}"] if ssv else [])
        found = {name: r[f"identifier.{name}"][-1] for name in ("ks", "wn", "zeta")}
        print(f"GM(3/t,1) {label}: identified k_s = {found['ks']:.4f}, ω_n = {found['wn']:.5f}, ζ = {found['zeta']:.4f}")
        ax.plot(r["time"], r["process.y"],
                label=f"{label} → {found['ks']:.3f}, {found['wn']:.4f}, {found['zeta']:.3f}")
    ax.set_xlabel("t [s]")
    ax.set_title("GM(3/t,1) identification from the step response (Ts = 0.5 s)")
    ax.legend()
    save(figure, "gm3t1")


if __name__ == "__main__":
    FIGURES.mkdir(parents=True, exist_ok=True)
    simulation_3_2()
    simulations_3_3_and_3_4()
    simulations_3_5_to_3_7()
    grey_pi_versus_pi()
    figure_3_12()
    gm3t1_identification()
