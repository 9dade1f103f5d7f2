"""Scale: µs per master step for a chain of N of our FMUs, N = 10, 50, 100, and the linear fit.

    python benchmarks/bench_scale.py [--steps 2000] [--repeat 3] [--sizes 10 50 100]

Two chains, each fed by a Step source, every connector recorded:

- ``FirstOrderFilter`` × N (no direct feedthrough): per step and FMU one fmi2SetReal, one
  fmi2DoStep and one fmi2GetReal, exactly the calls of the floor;
- ``Gain`` × N (direct feedthrough): the master also settles the chain within the instant
  (route, set, re-read each Gain in dependency order), so it makes one more set and get per
  FMU and step than the floor, which lets the chain lag one step per block.

For each N the stepping loop of ``cosim.run.simulation.run`` is timed (metadata ``loop_seconds``,
best of ``--repeat``, the repeats interleaved over the sizes), and so is `floor.run_floor` (a
hand-written ctypes Jacobi loop) on the same FMUs.  ``numpy.polyfit`` fits time = a + b·N; b
is the cost per FMU and step, the difference of the two slopes the master's own overhead per
FMU.  The floor extracts one copy of the FMU's library per instance (as libcosim does), cosim
one per FMU file, so at large N the floor can be the slower of the two.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]  # the root first: tests/cosim would shadow cosim

import cosim  # noqa: E402
from bench_master import floor_spec, time_cosim  # noqa: E402
from floor import run_floor  # noqa: E402
from greyfmu.build import build_fmus  # noqa: E402
from ssdgen import ssd_text, write_system  # noqa: E402

STEP = 0.01


def chain_system(folder: Path, block: str, n: int, fmus: dict[str, Path], stop: float) -> Path:
    """A Step source and ``n`` ``block`` FMUs in series: source.y -> b1.u, b_i.y -> b_{i+1}.u."""
    components = {"source": ("Step.fmu", {"y": "output"})}
    connections = []
    upstream = "source"
    for i in range(1, n + 1):
        name = f"b{i}"
        components[name] = (f"{block}.fmu", {"u": "input", "y": "output"})
        connections.append((upstream, "y", name, "u"))
        upstream = name
    text = ssd_text(f"{block}_chain_{n}", components, connections, stop=stop, step=STEP,
                    parameters={"source": {"t_step": 0.0}})
    return write_system(folder, {"Step.fmu": fmus["Step"], f"{block}.fmu": fmus[block]}, text)


def time_floor(folder: Path, stop: float) -> float:
    prepared = cosim.prepare(folder, stop_time=stop, use_providers=False)
    try:
        fmus, conns, signals = floor_spec(prepared.plan)
        return run_floor(fmus, conns, 0.0, stop, STEP, signals)[0]
    finally:
        prepared.close()


def fit(sizes: list[int], us: list[float]) -> tuple[float, float, float]:
    """time = a + b·N by least squares: (a, b, R²)."""
    b, a = np.polyfit(sizes, us, 1)
    predicted = a + b * np.asarray(sizes, dtype=float)
    residual = np.sum((np.asarray(us) - predicted) ** 2)
    total = np.sum((np.asarray(us) - np.mean(us)) ** 2)
    return float(a), float(b), float(1.0 - residual / total)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 50, 100])
    args = parser.parse_args()
    fmus = {p.stem: p for p in build_fmus(["Step", "FirstOrderFilter", "Gain"])}
    stop = args.steps * STEP
    print(f"{args.steps} steps of {STEP} s, best of {args.repeat}; µs per master step")
    print(f"{'chain':18} {'N':>4} {'cosim':>10} {'floor':>10} {'cosim/floor':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for block in ("FirstOrderFilter", "Gain"):
            folders = {n: chain_system(Path(tmp) / f"{block}{n}", block, n, fmus, stop) for n in args.sizes}
            rows = {"cosim": {n: float("inf") for n in args.sizes}, "floor": {n: float("inf") for n in args.sizes}}
            for _ in range(args.repeat):  # repeats interleaved, so every size sees the machine's load changes
                for n, folder in folders.items():
                    rows["cosim"][n] = min(rows["cosim"][n], time_cosim(folder, stop) / args.steps * 1e6)
                    rows["floor"][n] = min(rows["floor"][n], time_floor(folder, stop) / args.steps * 1e6)
            for n in args.sizes:
                master, floor = rows["cosim"][n], rows["floor"][n]
                print(f"{block:18} {n:4d} {master:10.1f} {floor:10.1f} {master / floor:12.2f}", flush=True)
            slopes = {}
            for who, us in rows.items():
                a, slopes[who], r2 = fit(args.sizes, [us[n] for n in args.sizes])
                print(f"  {block} {who:5}: time = {a:7.1f} + {slopes[who]:5.2f}·N µs/step   (R² = {r2:.5f})")
            print(f"  master overhead per FMU and step: {slopes['cosim'] - slopes['floor']:.2f} µs")


if __name__ == "__main__":
    main()
