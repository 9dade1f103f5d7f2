"""The ranges over which chapter 2's claims hold, on the values the thesis leaves open (issue 46).

    nice -n 10 python docs/gain_scheduling_ranges_report.py      # about 150 runs, 5-10 minutes on one core

The thesis gives neither the set-point steps nor the disturbance sizes of §2.3; docs/gain_scheduling.md chose one
of each.  Here the verdicts are taken over a range of them:

- Sim. 2.1 (ssp/gs_sim2_1) forward (Kp(y) = sqrt(y - 0.72) rising) and reversed (``kp_falling.ssv``, Kp falling
  along the step), set-point 0.5 -> y_f for y_f from 1 to 10: the table's Kp(y) is defined on (0.76, 7) and constant
  beyond, so a step that ends at or above 7 leaves the range the simulation is about.  Claims: forward, "(2.10) has
  an unacceptable overshoot [...] (2.11)/(2.12) offset it"; reversed, "(2.10) will have a greatly over damped step
  response" (read: the more damped of the three, and settling).
- Ch. 5 (1) (ssp/gs_ch5_large_disturbance): the load step d from 2 to 60 with the gains scheduled on the set-point
  (every mode is then the fixed PID of y = 1) and on y; the smallest d at which each loop stops settling, found on
  the grid and refined by bisection.
- §2.3.4 (1), ch. 5 (2): "to achieve the desired control quality, more operating points are needed for FGS1 and
  FGS2": Sim. 2.3 (Kp varies) with a third operating point at y = 3.88 (the middle of the table), its gain from the
  case's ITAE rule (``ssp/gs_sim2_3/third_point_case*.ssv``).

Settled: after a load step (ch. 5) the oscillation dies out (the last 150 s swing under 0.01 or under 0.9 × that of the
150 s before); after a set-point step, into ±2 % of the step by the end of the run (cosim.present.metrics).
Runs are kept in build/studies/gain_scheduling_ranges.jsonl (docs/studies.py).  Writes
docs/gain_scheduling_ranges_tables.md.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

import cosim
from cosim.present.metrics import step_metrics
from studies import StudyCache, parameter_set

ROOT = Path(__file__).resolve().parents[1]
SSP = ROOT / "ssp"
TABLES = ROOT / "docs" / "gain_scheduling_ranges_tables.md"
CACHE = StudyCache("gain_scheduling_ranges")
TARGETS = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 6.5, 6.9, 7.0, 7.5, 8.0, 10.0)
"""Set-point after the step from 0.5 (Sim. 2.1); 4 is docs/gain_scheduling.md's choice."""
LOADS = (2.0, 4.0, 6.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 60.0)
"""Load steps d of ch. 5 (1); 6 is docs/gain_scheduling.md's choice."""
MODES = {1: "(2.10)", 2: "(2.11)", 3: "(2.12)"}
SIM_2_1_STOP = 1000.0
"""Long enough for a response that creeps (docs/gain_scheduling.md's runs stop at 300 s)."""


def simulate(scenario: Path, sets: tuple[str, ...], values: Mapping[str, int | float], stop: float) -> np.ndarray:
    folder = scenario if scenario.is_dir() else scenario.parent
    with tempfile.TemporaryDirectory() as temp:
        files = [folder / f"{s}.ssv" for s in sets] + ([parameter_set(values, Path(temp) / "values.ssv")] if values else [])
        return cosim.simulate(scenario, stop_time=stop, parameter_sets=files)


def step_run(direction: str, target: float, mode: int) -> dict[str, float]:
    """Sim. 2.1 set-point 0.5 -> target at 10 s, Kp rising (forward) or falling (reversed) along the step; 1000 s."""
    sets = ("step_up" if direction == "forward" else "kp_falling", f"mode{mode}")
    description = {"part": "sim2_1", "sets": sets, "target": target, "stop": SIM_2_1_STOP}

    def measure() -> dict[str, float]:
        r = simulate(SSP / "gs_sim2_1", sets, {"setpoint.final": target}, SIM_2_1_STOP)
        m = step_metrics(r["time"], r["plant.y"], r["setpoint.y"], t0=10.0)
        tail = r["time"] >= SIM_2_1_STOP - 200.0
        return {"overshoot": m["overshoot"], "rise": m["rise_time"], "settling": m["settling_time"],
                "tail_ptp": float(np.ptp(r["plant.y"][tail])), "finite": bool(np.all(np.isfinite(r["plant.y"])))}
    return CACHE.get(description, measure)


def load_run(schedule: str, mode: int, d: float) -> dict[str, float]:
    """Ch. 5 (1): set-point 1, load step d at 50 s, 600 s; W = the set-point or y."""
    scenario = SSP / "gs_ch5_large_disturbance" / ("SystemStructure.ssd" if schedule == "set-point" else "scheduled_on_y.ssd")
    description = {"part": "ch5", "schedule": schedule, "mode": mode, "d": d, "v": 2}

    def measure() -> dict[str, float]:
        r = simulate(scenario, (f"mode{mode}",), {"load.amplitude": d}, 600.0)
        y, t = r["plant.y"], r["time"]
        if not np.all(np.isfinite(y)):
            return {"peak": float("inf"), "tail_ptp": float("inf"), "before_ptp": float("inf")}
        return {"peak": float(np.max(np.abs(y))), "tail_ptp": float(np.ptp(y[t > 450.0])),
                "before_ptp": float(np.ptp(y[(t > 300.0) & (t <= 450.0)]))}
    return CACHE.get(description, measure)


def settles(m: Mapping[str, float]) -> bool:
    """The oscillation after the load step dies out: the last 150 s swing under 0.01, or under 0.9 × the 150 s before."""
    return bool(np.isfinite(m["tail_ptp"]) and (m["tail_ptp"] < 0.01 or m["tail_ptp"] < 0.9 * m["before_ptp"]))


def boundary(schedule: str, mode: int) -> tuple[float, float] | None:
    """(largest settling d, smallest non-settling d) on the grid, refined by bisection to 0.1; None if all settle."""
    grid = [(d, settles(load_run(schedule, mode, d))) for d in LOADS]
    failing = [d for d, ok in grid if not ok]
    if not failing:
        return None
    high = failing[0]
    passing = [d for d, ok in grid if ok and d < high]
    if not passing:
        return (0.0, high)
    low = passing[-1]
    while high - low > 0.25:
        middle = (low + high) / 2
        low, high = (middle, high) if settles(load_run(schedule, mode, middle)) else (low, middle)
    return low, high


def fmt(value: float, digits: int = 1) -> str:
    return "—" if not np.isfinite(value) else f"{value:.{digits}f}"


def sim_2_1_part() -> list[str]:
    lines = ["## Sim. 2.1 over the step's end point (set-point 0.5 → y_f at 10 s)", "",
             "Overshoot % / settling s (±2 % of the step, — = not settled by 1000 s) per integral mode. Forward: Kp(y) = sqrt(y − 0.72) "
             "on (0.76, 7), 2.5 above; reversed (`kp_falling.ssv`): sqrt(7.04 − y), 0.2 above 7. Claim forward: (2.10)'s "
             "overshoot \"unacceptable\" (> 20 %, the thesis's bound below 0.76, and more than twice (2.12)'s) while "
             "(2.11)/(2.12) offset it; reversed: (2.10) the most damped of the three (least overshoot) and settled.", "",
             "| y_f | forward (2.10) | (2.11) | (2.12) | forward claim | reversed (2.10) | (2.11) | (2.12) | reversed claim |",
             "|---|---|---|---|---|---|---|---|---|"]
    for target in TARGETS:
        cells, verdicts = [], []
        for direction in ("forward", "reversed"):
            runs = {mode: step_run(direction, target, mode) for mode in MODES}
            cells.append(" | ".join(f"{fmt(m['overshoot'])} / {fmt(m['settling'], 0)}" for m in runs.values()))
            if direction == "forward":
                held = runs[1]["overshoot"] > max(20.0, 2 * runs[3]["overshoot"]) and np.isfinite(runs[3]["settling"])
            else:
                held = (runs[1]["overshoot"] < min(runs[2]["overshoot"], runs[3]["overshoot"])
                        and np.isfinite(runs[1]["settling"]))
            verdicts.append("holds" if held else "**fails**")
        lines.append(f"| {target:g} | {cells[0]} | {verdicts[0]} | {cells[1]} | {verdicts[1]} |")
        print(lines[-1], flush=True)
    return lines + [""]


def ch5_part() -> list[str]:
    lines = ["## Ch. 5 (1): the load step d at which each loop stops settling", "",
             "Set-point 1, load step d at 50 s, 600 s; peak = largest |y|, p-p = peak-to-peak of y over 450-600 s; the loop "
             "settles when its oscillation dies out (p-p under 0.01, or under 0.9 × that of 300-450 s). "
             "Scheduled on the set-point every mode is the fixed PID of y = 1 (Kc = 1.6069/Kp(1) = 3.04).", "",
             "| gains scheduled on | mode | " + " | ".join(f"d = {d:g}: peak / tail p-p" for d in LOADS)
             + " | settles up to d | stops settling from d |", "|" + "---|" * (len(LOADS) + 4)]
    for schedule, modes in (("set-point", (1, 3)), ("y", (1, 2, 3))):
        for mode in modes:
            runs = [load_run(schedule, mode, d) for d in LOADS]
            edge = boundary(schedule, mode)
            low, high = ("all", "—") if edge is None else (f"{edge[0]:g}", f"{edge[1]:g}")
            lines.append(f"| {schedule} | {MODES[mode]} | " + " | ".join(
                f"{fmt(m['peak'], 2)} / {fmt(m['tail_ptp'], 2)}" for m in runs) + f" | {low} | {high} |")
            print(lines[-1], flush=True)
    return lines + [""]


def third_point_run(case: int, law: str, points: int) -> dict[str, float]:
    """Sim. 2.3 CASE `case`, set-point 1 -> 4, with the scenario's two operating points or a third at y = 3.88
    (ssp/gs_sim2_3/third_point_case*.ssv: the case's ITAE gain there)."""
    sets = (f"case{case}", law, *((f"third_point_case{case}",) if points == 3 else ()))
    description = {"part": "third_point", "case": case, "law": law, "points": points}

    def measure() -> dict[str, float]:
        r = simulate(SSP / "gs_sim2_3", sets, {}, 400.0)
        m = step_metrics(r["time"], r["plant.y"], r["setpoint.y"], t0=10.0)
        return {"overshoot": m["overshoot"], "settling": m["settling_time"], "IAE": m["IAE"]}
    return CACHE.get(description, measure)


def third_point_part() -> list[str]:
    lines = ["## §2.3.4 (1): a third operating point for FGS1/FGS2 (Sim. 2.3, set-point 1 → 4)", "",
             "Third point at y = 3.88 (`third_point_case*.ssv`) with the case's ITAE gain Kc = 0.2961/Kp(3.88); Ti, Td as "
             "the other points. Overshoot % / settling s / IAE.", "",
             "| case | law | 2 points | 3 points | MFGS, 2 points |", "|---|---|---|---|---|"]
    for case in (1, 2, 3):
        mfgs = third_point_run(case, "mfgs", 2)
        for law in ("fgs1", "fgs2"):
            two, three = third_point_run(case, law, 2), third_point_run(case, law, 3)
            lines.append(f"| {case} | {law.upper()} | " + " | ".join(
                f"{fmt(m['overshoot'])} / {fmt(m['settling'], 0)} / {fmt(m['IAE'])}" for m in (two, three, mfgs)) + " |")
            print(lines[-1], flush=True)
    return lines + [""]


def main() -> None:
    text = ("# Chapter 2 over the values the thesis leaves open (generated by docs/gain_scheduling_ranges_report.py)\n\n"
            + "\n".join(sim_2_1_part() + ch5_part() + third_point_part()) + "\n")
    TABLES.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
