"""Digital PI of Zhou et al. (2006): write the ssp/dpi_* scenarios, run them, print the variance
tables and save the figures docs/figures/dpi_*.png.

    python docs/digital_pi_report.py                   # write scenarios, run, tables, figures
    python docs/digital_pi_report.py --write           # only (re)write the scenario folders
    python docs/digital_pi_report.py --identification  # only the ELS-vs-DARE Kalman gain table
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from greyfmu.control.digital_pi import design_digital_pi, stationary_variances, write_design_ssv
from greyfmu.control.digital_pi.examples import UNIT_DISC, Example, ch47, wood_berry
from greyfmu.control.digital_pi.gain_study import Route, compare_gains
from greyfmu.ssv import matrix_parameters, write_parameter_set
from figure_files import save_figure

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"

SCENARIOS = {
    # name: (example, event times r2, d1, d2, stop, regulation stop)
    "dpi_ch47": (ch47, (1.0, 2.0, 3.0), 4.0, 20.0),
    "dpi_wood_berry": (wood_berry, (200.0, 400.0, 600.0), 800.0, 2000.0),
}
BLT = {"Kc1": 0.375, "Ti1": 8.29, "Kc2": -0.075, "Ti2": 23.6}
"""Luyben's (1986) BLT multiloop PI settings for the Wood–Berry column (minutes; from memory)."""

_HEADER = """<?xml version="1.0" encoding="UTF-8"?>
<!-- {comment} -->
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"
    version="1.0" name="{name}">
  <ssd:System name="loop">
    <ssd:Elements>
"""
_FOOTER = """    </ssd:Elements>
    <ssd:Connections>
{connections}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop:g}">
    <ssd:Annotations>
      <ssc:Annotation type="org.greyfmu.simulation">
        <greyfmu:Simulation stepSize="{step:g}" algorithm="gauss-seidel"/>
      </ssc:Annotation>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm>
          <osp:FixedStepAlgorithm baseStepSize="{step:g}"/>
        </osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def _component(name: str, fmu: str, connectors: dict[str, str], binding: str | dict[str, float]) -> str:
    lines = [f'      <ssd:Component name="{name}" source="resources/{fmu}.fmu">', "        <ssd:Connectors>"]
    lines += [f'          <ssd:Connector name="{c}" kind="{kind}"><ssc:Real/></ssd:Connector>'
              for c, kind in connectors.items()]
    lines += ["        </ssd:Connectors>", "        <ssd:ParameterBindings>"]
    if isinstance(binding, str):
        lines.append(f'          <ssd:ParameterBinding source="{binding}"/>')
    else:
        lines += ["          <ssd:ParameterBinding>", "            <ssd:ParameterValues>",
                  f'              <ssv:ParameterSet version="1.0" name="{name}">', "                <ssv:Parameters>"]
        lines += [f'                  <ssv:Parameter name="{k}"><ssv:Real value="{v:g}"/></ssv:Parameter>'
                  for k, v in binding.items()]
        lines += ["                </ssv:Parameters>", "              </ssv:ParameterSet>",
                  "            </ssd:ParameterValues>", "          </ssd:ParameterBinding>"]
    lines += ["        </ssd:ParameterBindings>", "      </ssd:Component>"]
    return "\n".join(lines) + "\n"


def _sources(times: tuple[float, float, float]) -> str:
    t2, t3, t4 = times
    steps = {"ref1": (0.0, 1.0), "ref2": (t2, 1.0), "dist1": (t3, -1.0), "dist2": (t4, -1.0)}
    return "".join(_component(name, "Step", {"y": "output"}, {"t_step": t, "initial": 0.0, "final": final})
                   for name, (t, final) in steps.items())


def _connect(a: str, b: str) -> str:
    (sa, ca), (sb, cb) = a.split("."), b.split(".")
    return f'      <ssd:Connection startElement="{sa}" startConnector="{ca}" endElement="{sb}" endConnector="{cb}"/>'


def plant_parameters(example: Example) -> dict[str, float | int]:
    """StochasticLTI parameters of an example, without noise (the regulation set switches it on)."""
    plant = example.plant
    tau = np.where(plant.B != 0.0, example.tau, 0.0)
    values: dict[str, float | int] = {"n": plant.n, "m": plant.m, "p": plant.p, "noise_period": example.Ts}
    for name, matrix in {"A": plant.A, "B": plant.B, "tau": tau, "C": plant.C, "V": plant.V}.items():
        values.update(matrix_parameters(name, matrix, skip_zeros=False))
    values.update(matrix_parameters("Qeta", np.zeros((plant.p, plant.p)), skip_zeros=False))
    return values


def regulation_parameters(example: Example) -> dict[str, float | int]:
    """System-level set: r = 0, no output steps, innovations of covariance Q_eta on (test (41)/(42))."""
    values: dict[str, float | int] = {f"{s}.final": 0.0 for s in ("ref1", "ref2", "dist1", "dist2")}
    values.update({f"plant.{k}": v for k, v in matrix_parameters("Qeta", example.Q_eta).items()})
    values["plant.seed"] = 1
    return values


def write_scenarios() -> None:
    for name, (make, times, stop, _) in SCENARIOS.items():
        example = make()
        design = design_digital_pi(example.plant, example.Ts, example.tau, example.alpha, example.beta,
                                   example.q, example.r)
        folder = ROOT / "ssp" / name
        folder.mkdir(parents=True, exist_ok=True)
        write_design_ssv(design, folder / "controller.ssv")
        if (example.alpha, example.beta) != UNIT_DISC:
            unit = design_digital_pi(example.plant, example.Ts, example.tau, *UNIT_DISC, example.q, example.r)
            write_design_ssv(unit, folder / "unit_disc.ssv", component="controller",
                             comment=f"{example.name}: the same digital PI designed in the unit disc (alpha = 1, "
                                     "beta = 0, the paper's Example 2) instead of the scenario's disc; "
                                     "system-level set written by docs/digital_pi_report.py")
        write_parameter_set(folder / "plant.ssv", "plant", plant_parameters(example),
                            f"{example.name}: plant (1) for the StochasticLTI FMU, written by docs/digital_pi_report.py")
        write_parameter_set(folder / "regulation.ssv", "regulation", regulation_parameters(example),
                            "Stochastic regulation test: r = 0, no steps, innovation noise on (system-level set)")
        controller = _component("controller", "DigitalPI", {**{f"r{i}": "input" for i in (1, 2)},
                                                             **{f"y{i}": "input" for i in (1, 2)},
                                                             **{f"u{i}": "output" for i in (1, 2)}}, "controller.ssv")
        plant = _component("plant", "StochasticLTI", {"u1": "input", "u2": "input", "d1": "input", "d2": "input",
                                                       "y1": "output", "y2": "output"}, "plant.ssv")
        connections = ["ref1.y", "controller.r1"], ["ref2.y", "controller.r2"], ["plant.y1", "controller.y1"], \
            ["plant.y2", "controller.y2"], ["controller.u1", "plant.u1"], ["controller.u2", "plant.u2"], \
            ["dist1.y", "plant.d1"], ["dist2.y", "plant.d2"]
        comment = (f"Zhou et al. (2006) deterministic test on the {example.name}: r1 step at 0, r2 at {times[0]:g}, "
                   f"-1 on y1 at {times[1]:g} and on y2 at {times[2]:g}. The controller precedes the plant so "
                   "Gauss-Seidel hands u(kT) to the plant at kT (no extra delay).")
        text = _HEADER.format(comment=comment, name=name) + _sources(times) + controller + plant
        text += _FOOTER.format(connections="\n".join(_connect(a, b) for a, b in connections), stop=stop, step=example.Ts)
        (folder / "SystemStructure.ssd").write_text(text)
    _write_decentralised()


def _write_decentralised() -> None:
    """Wood–Berry with two SISO PIs (BLT tuning) on the same plant and tests."""
    example = wood_berry()
    _, times, stop, _ = SCENARIOS["dpi_wood_berry"]
    folder = ROOT / "ssp" / "dpi_wood_berry_decentral"
    folder.mkdir(parents=True, exist_ok=True)
    write_parameter_set(folder / "plant.ssv", "plant", plant_parameters(example),
                        f"{example.name}: plant (1) for the StochasticLTI FMU, written by docs/digital_pi_report.py")
    write_parameter_set(folder / "regulation.ssv", "regulation", regulation_parameters(example),
                        "Stochastic regulation test: r = 0, no steps, innovation noise on (system-level set)")
    text = _HEADER.format(comment="Wood-Berry column under two SISO PIs (y1-u1, y2-u2), BLT settings of Luyben "
                          "(1986) Kc = 0.375, Ti = 8.29 min and Kc = -0.075, Ti = 23.6 min, sampled at 1 min; the "
                          "comparison of dpi_wood_berry as the paper compares with Huang and Huang (2004).",
                          name="dpi_wood_berry_decentral") + _sources(times)
    for i in (1, 2):
        text += _component(f"pi{i}", "PID", {"r": "input", "y": "input", "u": "output"},
                           {"Kc": BLT[f"Kc{i}"], "Ti": BLT[f"Ti{i}"], "Td": 0.0, "Ts": example.Ts})
    text += _component("plant", "StochasticLTI", {"u1": "input", "u2": "input", "d1": "input", "d2": "input",
                                                   "y1": "output", "y2": "output"}, "plant.ssv")
    connections = [("ref1.y", "pi1.r"), ("ref2.y", "pi2.r"), ("plant.y1", "pi1.y"), ("plant.y2", "pi2.y"),
                   ("pi1.u", "plant.u1"), ("pi2.u", "plant.u2"), ("dist1.y", "plant.d1"), ("dist2.y", "plant.d2")]
    text += _FOOTER.format(connections="\n".join(_connect(a, b) for a, b in connections), stop=stop, step=example.Ts)
    (folder / "SystemStructure.ssd").write_text(text)


def run_all() -> dict[str, dict[str, np.ndarray]]:
    """Deterministic and regulation runs of every scenario."""
    import cosim

    results = {}
    for name, regulation_stop in [("dpi_ch47", 20.0), ("dpi_wood_berry", 2000.0), ("dpi_wood_berry_decentral", 2000.0)]:
        folder = ROOT / "ssp" / name
        results[name] = {"deterministic": cosim.simulate(folder),
                         "regulation": cosim.simulate(folder, stop_time=regulation_stop,
                                                      parameter_sets=[folder / "regulation.ssv"])}
    folder = ROOT / "ssp" / "dpi_wood_berry"
    unit = folder / "unit_disc.ssv"
    results["dpi_wood_berry_unit_disc"] = {"deterministic": cosim.simulate(folder, parameter_sets=[unit]),
                                           "regulation": cosim.simulate(folder, stop_time=2000.0,
                                                                        parameter_sets=[unit, folder / "regulation.ssv"])}
    return results


def variances(result: np.ndarray, inputs: list[str]) -> list[float]:
    """E{y1²}, E{y2²}, E{u1²}, E{u2²} of a regulation run (time averages, first 10 % dropped)."""
    keep = result["time"] >= 0.1 * result["time"][-1]
    return [float(np.mean(result[c][keep] ** 2)) for c in ["plant.y1", "plant.y2", *inputs]]


def report(results: dict) -> str:
    lines = ["| loop | E{y1²} | E{y2²} | E{u1²} | E{u2²} |", "|---|---|---|---|---|"]
    for name, example in [("dpi_ch47", ch47()), ("dpi_wood_berry", wood_berry())]:
        design = design_digital_pi(example.plant, example.Ts, example.tau, example.alpha, example.beta,
                                   example.q, example.r)
        var_y, var_u = stationary_variances(design, example.Q_eta)
        simulated = variances(results[name]["regulation"], ["controller.u1", "controller.u2"])
        lines.append(f"| {name} digital PI, simulated | " + " | ".join(f"{v:.4g}" for v in simulated) + " |")
        lines.append(f"| {name} digital PI, Lyapunov | " + " | ".join(f"{v:.4g}" for v in [*var_y, *var_u]) + " |")
        if (example.alpha, example.beta) != UNIT_DISC:
            unit = design_digital_pi(example.plant, example.Ts, example.tau, *UNIT_DISC, example.q, example.r)
            var_y, var_u = stationary_variances(unit, example.Q_eta)
            simulated = variances(results[f"{name}_unit_disc"]["regulation"], ["controller.u1", "controller.u2"])
            lines.append(f"| {name} digital PI, unit disc (unit_disc.ssv), simulated | "
                         + " | ".join(f"{v:.4g}" for v in simulated) + " |")
            lines.append(f"| {name} digital PI, unit disc (unit_disc.ssv), Lyapunov | "
                         + " | ".join(f"{v:.4g}" for v in [*var_y, *var_u]) + " |")
    simulated = variances(results["dpi_wood_berry_decentral"]["regulation"], ["pi1.u", "pi2.u"])
    lines.append("| dpi_wood_berry decentralised PI (BLT), simulated | " + " | ".join(f"{v:.4g}" for v in simulated) + " |")
    return "\n".join(lines)


IDENTIFICATION = {"CH-47": (ch47, (1000, 4000, 16000, 64000, 256000)),
                  "Wood-Berry": (wood_berry, (1000, 4000, 16000, 64000))}
"""Data lengths of the identification table; seed 3, dither 0.1 on every input, 4000 validation samples."""


def _cells(route: Route) -> list[str]:
    prediction = "refused" if route.prediction is None else ", ".join(f"{v:.3g}" for v in route.prediction)
    regulation = "—" if route.regulation is None else ", ".join(f"{v:.4g}" for v in route.regulation)
    return [f"{route.gain_error:.3f}", prediction, regulation]


def identification_table() -> str:
    """The paper's ELS route to the Kalman gain against the DARE gain as the data length grows."""
    lines = ["| plant | N | ARMAX unknown: ‖ΔK‖/‖K‖ | its prediction var (y1, y2) | model known: ‖ΔK‖/‖K‖ "
             "| its prediction var | its loop E{y1²}, E{y2²} | DARE gain: prediction var | its loop E{y²} |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, (make, lengths) in IDENTIFICATION.items():
        example = make()
        for N in lengths:
            row = compare_gains(example, N, seed=3, dither=0.1)
            unknown = _cells(row.unknown)[:2]
            known = _cells(row.known)
            kalman = _cells(row.kalman)[1:]
            lines.append(f"| {name} | {N} | " + " | ".join(unknown + known + kalman) + " |")
    return "\n".join(lines)


def figures(results: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    for name, unit in [("dpi_ch47", "s"), ("dpi_wood_berry", "min"), ("dpi_wood_berry_unit_disc", "min")]:
        for test in ("deterministic", "regulation"):
            fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
            ours = results[name][test]
            for i in (1, 2):
                axes[0].plot(ours["time"], ours[f"plant.y{i}"], label=f"y{i} digital PI")
                axes[1].step(ours["time"], ours[f"controller.u{i}"], where="post", label=f"u{i} digital PI")
            if name.startswith("dpi_wood_berry"):
                other = results["dpi_wood_berry_decentral"][test]
                for i in (1, 2):
                    axes[0].plot(other["time"], other[f"plant.y{i}"], "--", label=f"y{i} decentralised PI")
                    axes[1].step(other["time"], other[f"pi{i}.u"], "--", where="post", label=f"u{i} decentralised PI")
            axes[0].set_ylabel("outputs")
            axes[1].set_ylabel("inputs")
            axes[1].set_xlabel(f"time [{unit}]")
            for ax in axes:
                ax.grid(True)
                ax.legend(fontsize=7, ncol=2)
            fig.suptitle(f"{name}: {test} test")
            fig.tight_layout()
            save_figure(fig, FIGURES / f"{name}_{test}.png", dpi=110)
            plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", action="store_true", help="only write the scenario folders")
    parser.add_argument("--identification", action="store_true", help="only the identification table")
    args = parser.parse_args()
    if args.identification:
        print(identification_table())
        return
    write_scenarios()
    if args.write:
        return
    results = run_all()
    print(report(results))
    figures(results)
    print(identification_table())


if __name__ == "__main__":
    main()
