"""Native FMUs: the master's own cost per step, cosim against a C floor, a C container and two masters.

    python benchmarks/bench_native.py [--steps 20000] [--repeat 3] [--sizes 1 10 100]
                                      [--families c om] [--fmpy-max 10] [--markdown]

Systems (benchmarks/native_systems.py): N native FMI 2.0 CS FMUs, ``independent`` (N Van der Pol
oscillators, 2 outputs each; or N OpenModelica ``Mass_Damper``) and ``chained`` (the oscillator
or the mass, then N - 1 direct-feedthrough blocks in series: our C ``Lag`` or OpenModelica
``add``), ``--steps`` steps of 1 ms.  No FMU runs Python: what is left is the masters.

What each peer does, records and how it is timed (the stepping loop alone for every peer:
loading, unzipping, instantiation and initialisation are excluded):

* ``cosim python`` / ``cosim native``: ``cosim.run.simulation.run`` with ``kernel="python"`` or
  ``"native"`` (today's Python loop or the compiled one; the keyword is passed only when this
  cosim has it), every connector (outputs and inputs) recorded in memory; metadata
  ``loop_seconds``.
* ``C floor``: benchmarks/native_floor.c (compiled here, called through ctypes in the run's process,
  one library per FMU file as cosim loads them; a copy per instance made 99 OpenModelica
  ``add`` blocks 10× slower):
  fmi2DoStep, one batched fmi2GetReal and fmi2SetReal per FMU, the routing and cosim's
  feedthrough settling in a C loop, every output and input appended to a C array, timed in C.
  Its results equal cosim's to the last bit (tests/test_bench_native.py).
* ``container``: the fmu-manipulation-toolbox 2.0 container (``fmucontainer``, one thread) of
  the same FMUs, every embedded output exposed; stepped by the same C loop (one fmi2DoStep of
  1 ms and one fmi2GetReal of all its outputs per step, recorded in the C array), timed in C.
  The container is Jacobi: a feedthrough chain lags one step per block.
* ``libcosim``: libcosim 0.11.2 through libcosimpy (tests/peers.py, ``run_libcosim``) on the
  same SSP folder, Jacobi, every output in its time-series observer; ``execution.step(n)`` timed.
* ``fmpy.ssp``: ``fmpy.ssp.simulate_ssp`` on the packed ``.ssp`` (tests/peers.py), every SSD
  connector in its result array; from the first to the last ``do_step``.  Run up to
  ``--fmpy-max`` FMUs.

Each run has a fresh process of its own (`isolated`; one process for everything crashed after a
few minutes of OpenModelica instances and containers coming and going).  Each number is the best
of ``--repeat`` runs, the repeats interleaved over cases and peers.
Printed: µs per step per system and the ratios cosim/container, cosim/libcosim, cosim/floor for
each cosim kernel; and what writing the result adds, for CSV and Parquet: the wall time of
``run(prepared, output=...)`` (the file plus its journal, what ``cosim run -o`` does) minus that
of the same run in memory (best of ``--repeat``, `file_overhead`), in percent of the in-memory loop
time and in µs per step, with the fastest kernel, for systems of 10 FMUs or more.  A peer that cannot run a case gets the reason instead of a number.  ``--markdown``
prints the table of docs/performance.md.
"""
from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import tempfile
import time as _time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

import cosim  # noqa: E402
import cosim.run.simulation  # noqa: E402
from c_floor import compile_floor, run_c_floor  # noqa: E402
from cosim.cli import main as cosim_main  # noqa: E402
from native_systems import FAMILIES, System, build_container, build_family, native_system, write_native_system  # noqa: E402,E501
from peers import run_fmpy_ssp, run_libcosim  # noqa: E402

STEP = 1e-3
#: the cosim kernels this cosim has (``kernel`` keyword of `cosim.run.simulation.run`)
KERNELS = ("python", "native")
PEERS = ("cosim python", "cosim native", "C floor", "container", "libcosim", "fmpy.ssp")


@dataclass
class Case:
    """One system laid out for every peer: SSP folder, packed .ssp, container, floor spec."""

    system: System
    folder: Path
    ssp: Path
    container: Path | str          # the container FMU, or why there is none
    fmus: list                     # (name, path, {}) for the floor, per component
    outputs: dict[str, list[str]]
    feedthrough: list[str]
    best: dict[str, float] = field(default_factory=dict)   # peer -> µs per step
    why: dict[str, str] = field(default_factory=dict)      # peer -> why it has no number
    results: dict[str, np.ndarray] = field(default_factory=dict)  # peer -> its last result


def lay_out(system: System, fmus: dict[str, Path], folder: Path, stop: float) -> Case:
    """``system`` as SSP folder, packed .ssp and container under ``folder``."""
    ssd = write_native_system(system, fmus, folder / "ssp", stop, STEP)
    ssp = folder / "system.ssp"
    if cosim_main(["pack", str(ssd), "-o", str(ssp)]) != 0:
        raise RuntimeError(f"cosim pack failed on {ssd}")
    try:
        container: Path | str = build_container(system, fmus, folder / "container", STEP)
    except RuntimeError as e:
        container = f"fmucontainer failed: {str(e).splitlines()[0]}"
    prepared = cosim.prepare(ssd, stop_time=stop, use_providers=False)
    try:
        plan = prepared.plan
        floor_fmus = [(c, str(d.path), {}) for c, d in plan.fmus.items()]
        outputs = {c: [v.name for v in plan.outputs[c]] for c in plan.fmus}
        feedthrough = list(plan.feedthrough_sequence)
    finally:
        prepared.close()
    return Case(system, ssd, ssp, container, floor_fmus, outputs, feedthrough)


def cosim_run(case: Case, stop: float, kernel: str, output: Path | None = None) -> tuple[float, float, np.ndarray]:
    """(loop seconds, wall seconds of ``run``, samples) of one cosim run."""
    prepared = cosim.prepare(case.folder, stop_time=stop, use_providers=False)
    try:
        started = _time.perf_counter()
        result, meta = cosim.run.simulation.run(prepared, output=output, kernel=kernel)
        wall = _time.perf_counter() - started
    finally:
        prepared.close()
    if meta["kernel"] != kernel:
        raise RuntimeError(f"asked for kernel {kernel!r}, cosim ran {meta.get('kernel')!r}")
    return meta["loop_seconds"], wall, result


def run_peer(peer: str, case: Case, stop: float, floor_library: Path, fmpy_max: int) -> tuple[float, np.ndarray] | str:
    """(loop seconds, samples) of ``peer`` on ``case``, or why it cannot run the case."""
    if peer.startswith("cosim"):
        kernel = peer.split()[1]
        seconds, _, result = cosim_run(case, stop, kernel)
        return seconds, result
    if peer == "C floor":
        return run_c_floor(floor_library, case.fmus, case.outputs, case.system.connections, case.feedthrough,
                           0.0, stop, STEP)
    if peer == "container":
        if isinstance(case.container, str):
            return case.container
        exposed = {f"{c}_{v}": f"{c}.{v}" for c, vs in case.outputs.items() for v in vs}   # build_container's names
        seconds, result = run_c_floor(floor_library, [("container", str(case.container), {})],
                                      {"container": list(exposed)}, [], [], 0.0, stop, STEP, settle=False)
        result.dtype.names = ["time"] + [exposed[name.removeprefix("container.")] for name in result.dtype.names[1:]]
        return seconds, result
    signals = [f"{c}.{v}" for c, vs in case.outputs.items() for v in vs]
    timing: dict = {}
    if peer == "libcosim":
        result = run_libcosim(case.folder, 0.0, stop, STEP, signals, timing=timing)
        return timing["loop_seconds"], result
    if peer == "fmpy.ssp":
        if case.system.n > fmpy_max:
            return f"not run: more than --fmpy-max {fmpy_max} FMUs"
        result = run_fmpy_ssp(case.ssp, 0.0, stop, STEP, signals, timing=timing)
        return timing["loop_seconds"], result
    raise ValueError(f"unknown peer {peer!r}")


def bare(case: Case) -> Case:
    """``case`` without its measurements, to send to a run's process."""
    return replace(case, best={}, why={}, results={})


def isolated(function, *args):
    """``function(*args)`` in a fresh Python process (spawned), or why it has no result: many
    OpenModelica FMU instances and containers created and freed in one process crashed it with a
    segmentation fault after a few minutes, so every run gets a process of its own."""
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        try:
            return pool.submit(function, *args).result()
        except BrokenProcessPool:
            return "the process crashed (the run died, e.g. a segmentation fault)"


def file_overhead(case: Case, stop: float, folder: Path) -> dict[str, float]:
    """Seconds that writing CSV and Parquet (with the journal) add to a run, and the in-memory loop's.

    A first in-memory run warms the process up (imports, the FMU libraries loaded); the in-memory
    wall time is the shorter of a run before and one after the file runs."""
    kernel = KERNELS[-1]
    cosim_run(case, stop, kernel)
    loop, wall, _ = cosim_run(case, stop, kernel)
    walls = {}
    for suffix in ("csv", "parquet"):
        walls[suffix] = cosim_run(case, stop, kernel, output=folder / f"result.{suffix}")[1]
        for written in folder.glob("result.*"):
            written.unlink()
    loop_after, wall_after, _ = cosim_run(case, stop, kernel)
    wall, loop = min(wall, wall_after), min(loop, loop_after)
    return {"loop": loop, **{suffix: seconds - wall for suffix, seconds in walls.items()}}


def measure(families: list[str], sizes: list[int], steps: int, repeat: int, fmpy_max: int, folder: Path,
            files_from: int = 10) -> list[Case]:
    """Every case, every peer, best of ``repeat`` interleaved; the CSV/Parquet cost of the cases of
    ``files_from`` FMUs or more."""
    stop = steps * STEP
    library = compile_floor(folder)
    cases = []
    for family in families:
        fmus = build_family(family, folder / family)
        for topology in ("independent", "chained"):
            for n in sizes:
                if topology == "chained" and n < 2:
                    continue
                system = native_system(FAMILIES[family], topology, n)
                cases.append(lay_out(system, fmus, folder / f"{family}_{topology}_{n}", stop))
    overheads: dict[int, dict[str, float]] = {}
    for round_ in range(repeat):
        for index, case in enumerate(cases):
            print(f"round {round_ + 1}/{repeat}: {case.system.family.name}, {case.system.label}", file=sys.stderr,
                  flush=True)
            for peer in PEERS:
                outcome = isolated(run_peer, peer, bare(case), stop, library, fmpy_max)
                if isinstance(outcome, str):
                    case.why[peer] = outcome
                    continue
                seconds, case.results[peer] = outcome
                case.best[peer] = min(case.best.get(peer, float("inf")), seconds / steps * 1e6)
            if case.system.n >= files_from:
                best = overheads.setdefault(index, {})
                added = isolated(file_overhead, bare(case), stop, case.folder.parent)
                if isinstance(added, str):
                    case.why["+csv"] = case.why["+parquet"] = added
                    continue
                for key, seconds in added.items():
                    best[key] = min(best.get(key, float("inf")), seconds)
    for index, case in enumerate(cases):
        best = overheads.get(index)
        if best:
            for suffix in ("csv", "parquet"):
                case.best[f"+{suffix} µs"] = best[suffix] / steps * 1e6
                case.best[f"+{suffix}"] = 100.0 * best[suffix] / best["loop"]
    return cases


def file_cost(case: Case, suffix: str) -> str:
    """"x % (y µs/step)": what writing the result adds, relative to the in-memory loop."""
    if f"+{suffix}" not in case.best:
        return case.why.get(f"+{suffix}", "—")
    return f"{case.best[f'+{suffix}']:.0f} % ({case.best[f'+{suffix} µs']:.2f})"


def cell(case: Case, peer: str) -> str:
    if peer in case.best:
        return f"{case.best[peer]:.2f}"
    return case.why.get(peer, "—")


def ratio(case: Case, kernel: str, peer: str) -> str:
    mine, theirs = case.best.get(f"cosim {kernel}"), case.best.get(peer)
    return f"{mine / theirs:.2f}" if mine is not None and theirs is not None else "—"


def table(cases: list[Case]) -> list[str]:
    """The table of docs/performance.md (markdown): µs per step, then ratios for each kernel, then file costs."""
    header = ["FMUs", "system", "N"] + [f"{p} µs" for p in PEERS]
    for kernel in KERNELS:
        header += [f"{kernel}/container", f"{kernel}/libcosim", f"{kernel}/floor"]
    header += ["CSV adds % (µs/step)", "Parquet adds % (µs/step)"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for case in cases:
        row = [case.system.family.name, case.system.topology, str(case.system.n)]
        row += [cell(case, p) for p in PEERS]
        for kernel in KERNELS:
            row += [ratio(case, kernel, "container"), ratio(case, kernel, "libcosim"), ratio(case, kernel, "C floor")]
        row += [file_cost(case, "csv"), file_cost(case, "parquet")]
        lines.append("| " + " | ".join(row) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 10, 100])
    parser.add_argument("--families", nargs="+", default=sorted(FAMILIES), choices=sorted(FAMILIES))
    parser.add_argument("--fmpy-max", type=int, default=10, help="largest system fmpy.ssp runs")
    parser.add_argument("--markdown", action="store_true", help="print the table of docs/performance.md")
    args = parser.parse_args()
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        cases = measure(args.families, args.sizes, args.steps, args.repeat, args.fmpy_max, Path(tmp))
    after = os.getloadavg()
    print(f"{args.steps} steps of {STEP * 1e3:g} ms, best of {args.repeat} (interleaved), µs per step; "
          f"cosim kernels: {', '.join(KERNELS)}; file costs with kernel {KERNELS[-1]}; "
          f"load average {load[0]:.2f} before, {after[0]:.2f} after, {os.cpu_count()} cores")
    if args.markdown:
        print("\n".join(table(cases)))
        return
    for case in cases:
        print(f"\n{case.system.family.name}, {case.system.label}")
        for peer in PEERS:
            print(f"  {peer:13} {cell(case, peer):>10}")
        for kernel in KERNELS:
            print(f"  cosim {kernel}: / container {ratio(case, kernel, 'container')}, / libcosim "
                  f"{ratio(case, kernel, 'libcosim')}, / floor {ratio(case, kernel, 'C floor')}")
        if "+csv" in case.best:
            print(f"  writing CSV adds {file_cost(case, 'csv')}, Parquet {file_cost(case, 'parquet')}")


if __name__ == "__main__":
    main()
