"""Cost of hosting a Model Exchange FMU: gemseo-fmu's Mass_Damper.fmu through its ME interface at
h = 0.01 s (CVODE in the master) against its Co-Simulation export at h = 5e-4 s (explicit Euler inside
the FMU, the largest stable step) over the same simulated span.

    python benchmarks/bench_me.py [--span 10] [--repeat 3]

The plant runs alone with a constant force f = 1000 N bound as a start value (no input changes), and
then with an input that changes at every communication point (the closed loop of
ssp/pid_mass_damper_me, where every step starts with an input event and a solver restart).  Figures
are the best of ``--repeat`` runs of the stepping loop (``loop_seconds`` in the run metadata: no
unzipping, instantiation or initialisation), in µs per communication step and per simulated second.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # the root first: tests/cosim would shadow cosim

from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system

from cosim.plan.prepare import prepare
from cosim.run import simulation


def loop_seconds(path: Path, repeat: int, **options) -> tuple[float, int]:
    best, steps = float("inf"), 0
    for _ in range(repeat):
        prepared = prepare(path, **options)
        try:
            _, metadata = simulation.run(prepared)
        finally:
            prepared.close()
        best, steps = min(best, metadata["loop_seconds"]), metadata["steps"]
    return best, steps


def plant_alone(folder: Path, implementation: str, span: float, step: float) -> Path:
    text = ssd_text("plant", {"plant": ("Mass_Damper.fmu", {"f": "input", "y": "output"})}, [], stop=span,
                    step=step, parameters={"plant": {"f": 1000.0}})
    text = text.replace('<ssd:Component name="plant" ',
                        f'<ssd:Component name="plant" implementation="{implementation}" ')
    return write_system(folder, {"Mass_Damper.fmu": gemseo_fmu_dir() / "Mass_Damper.fmu"}, text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--span", type=float, default=10.0, help="simulated seconds (default 10)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for implementation, step in (("ModelExchange", 0.01), ("CoSimulation", 5e-4)):
            path = plant_alone(Path(tmp) / implementation, implementation, args.span, step)
            seconds, steps = loop_seconds(path, args.repeat)
            rows.append((f"Mass_Damper {implementation}, h = {step:g} s", seconds, steps))
    seconds, steps = loop_seconds(ROOT / "ssp/pid_mass_damper_me", args.repeat, fmu_dirs=[gemseo_fmu_dir()],
                                  stop_time=args.span)
    rows.append(("pid_mass_damper_me (3 FMUs, input event every step), h = 0.01 s", seconds, steps))
    print(f"{'run':68} {'steps':>7} {'µs/step':>9} {'s per simulated s':>18}")
    for name, seconds, steps in rows:
        print(f"{name:68} {steps:7d} {1e6 * seconds / steps:9.1f} {seconds / args.span:18.5f}")
    print(f"wall time CS(5e-4) / ME(0.01) for the same span: {rows[1][1] / rows[0][1]:.1f}")


if __name__ == "__main__":
    main()
