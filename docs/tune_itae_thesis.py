"""The thesis's ITAE-tuned reference PID (000_*, §2.3.1, (2.8)) against what cosim tune finds
(docs/tuning.md, tests/scenarios/tune/test_known_answers.py).

    python docs/tune_itae_thesis.py [--workers 2] [--evaluations 450]

(2.8) with the printed A..F gives, on the FOPDT of Simulation 2.1 at its low operating point
(K_p = 0.2, T = 20 s, tau = 4 s), Kc = (A/Kp)(tau/T)^-B, Ti = C tau^D T^(1-D), Td = E tau^F T^(1-F);
the thesis's simulations use Kc = 1.6069/Kp (A = 0.350) with the same Ti and Td.  The A..F are
an ITAE design (Lopez et al.'s load-disturbance table), so the question is which criterion
each set of gains minimises.  Both are tuned here with differential evolution on the
ssp/pid_fopdt loop in the thesis's PID form (derivative on the error, (2.6a); no anti-windup,
the limits +-100 never reached), over 0-100 s:

- load: the set-point held at 0, the load step d = -1 at 10 s, ITAE of that event;
- set-point: the step 0 -> 1 at 10 s (no load), ITAE of that event.

Writes docs/data/tune_itae_thesis.json (each gain set's ITAE and overshoot in both cases, the
tuned gains) and prints the table of docs/tuning.md.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "data" / "tune_itae_thesis.json"
SCENARIO = ROOT / "ssp" / "pid_fopdt"
KP, T, TAU = 0.2, 20.0, 4.0
#: (2.8)'s constants as printed (thesis 000_*, §2.3.1)
A, B, C, D, E, F = 1.357, 0.947, 1.176, 0.738, 0.381, 0.995
#: the thesis's PID form: derivative on the error, no anti-windup
FORM = ["controller.derivative_on=1", "controller.anti_windup=0"]
CASES = {"load": ["setpoint.final=0", "load.t_step=10"], "set-point": ["load.final=0"]}
OBJECTIVES = {"load": "ITAE:plant.y@disturbance", "set-point": "ITAE:plant.y@1"}
STOP = 100.0
BOUNDS = {"controller.Kc": (2.0, 80.0, "log"), "controller.Ti": (2.0, 60.0, "log"), "controller.Td": (0.2, 6.0, "log")}


def printed_gains() -> dict[str, float]:
    """(2.8) with the printed A..F."""
    return {"controller.Kc": A / KP * (TAU / T) ** -B, "controller.Ti": C * TAU ** D * T ** (1 - D),
            "controller.Td": E * TAU ** F * T ** (1 - F)}


def thesis_gains() -> dict[str, float]:
    """The gains the thesis's simulations run (Simulation 2.1: Kc = 1.6069/Kp, Ti = 7.1713, Td = 1.5363)."""
    return {"controller.Kc": 1.6069 / KP, "controller.Ti": 7.1713, "controller.Td": 1.5363}


def measure(gains: dict[str, float], case: str) -> dict[str, float]:
    """ITAE (and the set-point case's overshoot) of ``gains`` in ``case``: one run."""
    from cosim.run.simulation import run
    from cosim.plan.prepare import prepare as prepare_run
    from cosim.tune import loops_of
    from cosim.tune.measures import Measurement, MetricTerm

    values = [f"{k}={v!r}" for k, v in gains.items()]
    with prepare_run(SCENARIO, start_values=FORM + CASES[case] + values, stop_time=STOP) as prepared:
        _, loads, _ = loops_of(prepared)
        result = run(prepared).result
    event = "disturbance" if case == "load" else "1"
    terms = (MetricTerm("ITAE", "plant.y", "setpoint.y", event), MetricTerm("overshoot", "plant.y", "setpoint.y", "1"))
    measured = Measurement(terms, tuple(loads), stop=STOP)(result)
    return {"ITAE": measured[terms[0].name], "overshoot": measured[terms[1].name]}


def main() -> None:
    from cosim.tune import DifferentialEvolution, tune

    parser = argparse.ArgumentParser()
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--evaluations", type=int, default=450)
    args = parser.parse_args()
    sets = {"(2.8) as printed": printed_gains(), "the thesis's simulations (A = 0.350)": thesis_gains()}
    tuned = {}
    for case in CASES:
        began = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            result = tune(SCENARIO, BOUNDS, objective=OBJECTIVES[case], start_values=FORM + CASES[case],
                          stop_time=STOP, method=DifferentialEvolution(popsize=10), max_evaluations=args.evaluations,
                          workers=args.workers, output=tmp, report=False, progress=True)
        tuned[case] = {"gains": result.best.values, "ITAE": result.best.objective,
                       "evaluations": len(result.evaluations), "seconds": time.perf_counter() - began,
                       "message": result.message}
        sets[f"tuned for ITAE of the {case} event"] = result.best.values
    table = {name: {"gains": gains, **{case: measure(gains, case) for case in CASES}} for name, gains in sets.items()}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"tuned": tuned, "table": table, "stop": STOP, "form": FORM, "cases": CASES,
                               "bounds": BOUNDS}, indent=1) + "\n")
    print("| gains | Kc | Ti [s] | Td [s] | ITAE, load event | ITAE, set-point event | overshoot [%] |")
    print("|---|---|---|---|---|---|---|")
    for name, row in table.items():
        g = row["gains"]
        print(f"| {name} | {g['controller.Kc']:.4g} | {g['controller.Ti']:.4g} | {g['controller.Td']:.4g} | "
              f"{row['load']['ITAE']:.4g} | {row['set-point']['ITAE']:.4g} | {row['set-point']['overshoot']:.3g} |")
    for case, t in tuned.items():
        print(f"{case}: {t['evaluations']} evaluations, {t['seconds']:.0f} s, {t['message']}")


if __name__ == "__main__":
    main()
