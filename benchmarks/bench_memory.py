"""10⁶ steps × 50 recorded signals: peak memory and the result writer's share of the run time.

    python benchmarks/bench_memory.py [--steps 1000000] [--repeat 1] [--variants none csv parquet]

The system: a Ramp source (y = 0.37·t, 17 significant digits per sample) driving 12 inputs of
an ``Exchange`` FMU (benchmarks/fmus/Exchange.py, y_i = u_i), whose 12 outputs drive 12
inputs of a second one: 1 + 2·(12 + 12) = 49 connectors plus time = 50 recorded columns.
Each variant runs in a fresh Python process (so ``ru_maxrss`` is that run's peak resident
memory), through ``cosim.run.simulation.run`` as ``cosim run --output`` does (only ``time`` kept
in memory): ``none`` writes no file (the baseline), ``csv`` a CSV, ``parquet`` a Parquet file.
The writer's overhead is (run time with the file − run time without) / run time without,
with the run time from instantiation to the closed file, best of ``--repeat``.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]  # the root first: tests/cosim would shadow cosim

WIDTH = 12
STEP = 0.001


def write_scenario(folder: Path, exchange_fmu: Path, ramp_fmu: Path, steps: int) -> Path:
    from ssdgen import ssd_text, write_system

    ports = {f"u{i}": "input" for i in range(1, WIDTH + 1)} | {f"y{i}": "output" for i in range(1, WIDTH + 1)}
    components = {"ramp": ("Ramp.fmu", {"y": "output"}), "a": ("Exchange.fmu", ports), "b": ("Exchange.fmu", ports)}
    connections = [("ramp", "y", "a", f"u{i}") for i in range(1, WIDTH + 1)]
    connections += [("a", f"y{i}", "b", f"u{i}") for i in range(1, WIDTH + 1)]
    text = ssd_text("memory", components, connections, stop=steps * STEP, step=STEP,
                    parameters={"ramp": {"start_time": 0.0, "slope": 0.37, "final": 1e9}})
    return write_system(folder, {"Exchange.fmu": exchange_fmu, "Ramp.fmu": ramp_fmu}, text)


def child(folder: str, output: str | None) -> None:
    """One run in this process; prints its figures as JSON."""
    import cosim

    prepared = cosim.prepare(folder, use_providers=False)
    try:
        started = time.perf_counter()
        result, metadata = cosim.run.simulation.run(prepared, output=output, keep=[])
        seconds = time.perf_counter() - started
    finally:
        prepared.close()
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux
    print(json.dumps({"seconds": seconds, "loop_seconds": metadata["loop_seconds"], "peak_mb": peak_mb,
                      "rows": len(result)}))


def measure(folder: Path, variant: str, tmp: Path) -> dict:
    output = [] if variant == "none" else [str(tmp / f"result.{variant}")]
    proc = subprocess.run([sys.executable, __file__, "--child", str(folder), *output],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"the {variant} run failed:\n{proc.stderr}")
    figures = json.loads(proc.stdout.strip().splitlines()[-1])
    if output:
        path = Path(output[0])
        figures["file_mb"] = path.stat().st_size / 1e6
        if variant == "parquet":
            import pyarrow.parquet as pq
            meta = pq.ParquetFile(path).metadata
            figures["columns"], figures["file_rows"] = meta.num_columns, meta.num_rows
        else:
            with open(path, "rb") as f:
                header = f.readline()
                figures["columns"] = header.count(b",") + 1
                figures["file_rows"] = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 24), b""))
        path.unlink()
    return figures


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None)
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--variants", nargs="+", default=["none", "csv", "parquet"])
    args = parser.parse_args()
    from bench_exchange import build
    from greyfmu.build import build_fmus

    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        exchange = build(tmp / "fmus")["fast"]
        folder = write_scenario(tmp / "memory", exchange, build_fmus(["Ramp"])[0], args.steps)
        best: dict[str, dict] = {}
        for _ in range(args.repeat):
            for variant in args.variants:
                figures = measure(folder, variant, tmp)
                print(f"  {variant:8} {figures['seconds']:7.1f} s  peak RSS {figures['peak_mb']:6.1f} MB", flush=True)
                kept = best.get(variant)
                if kept is None or figures["seconds"] < kept["seconds"]:
                    best[variant] = figures | {"peak_mb": max(figures["peak_mb"], kept["peak_mb"] if kept else 0.0)}
    print(f"\n{args.steps} steps of {STEP} s, best of {args.repeat}")
    print(f"{'output':8} {'run [s]':>8} {'µs/step':>8} {'peak RSS [MB]':>14} {'file [MB]':>10} {'rows':>8} "
          f"{'columns':>8} {'writer overhead':>16}")
    base = best.get("none", {}).get("seconds")
    for variant, f in best.items():
        overhead = f"{100 * (f['seconds'] / base - 1):15.1f}%" if base and variant != "none" else ""
        print(f"{variant:8} {f['seconds']:8.1f} {f['seconds'] / args.steps * 1e6:8.1f} {f['peak_mb']:14.1f} "
              f"{f.get('file_mb', 0.0):10.1f} {f.get('file_rows', f['rows']):8d} {f.get('columns', '-')!s:>8} {overhead}")


if __name__ == "__main__":
    main()
