"""Recording: cosim's run with every value recorded, against a C loop that records the same values.

    python benchmarks/bench_recording.py [--sizes 10 1000] [--steps 20000 4000] [--repeat 5]
                                         [--baseline TREE] [--markdown]

Systems (benchmarks/native_systems.py, C family): ``independent N``, N Van der Pol oscillators of
2 outputs each (1 + 2N columns: 2001 at N = 1000), ``--steps`` steps of 1 ms (one per size).  No
FMU runs Python and each step's own work is ~0.01 µs per FMU, so what is left is the master and
its recording.  Four ways to record, each by cosim and by the C floor (benchmarks/native_floor.c,
compiled with cosim's own CSV formatter ``cosim/kernel/csvrows.c``; called through ctypes on
instances fmpy made, one library per FMU file as cosim loads them):

* ``memory``: every column kept in memory.  cosim: ``run(prepared)`` (`cosim.run.simulation.run`,
  the result array of `cosim.simulate`); floor: each row memcpy'd into one preallocated array.
* ``csv``: every column written to a CSV, only ``time`` kept in memory, as ``cosim run -o x.csv``
  (its journal included); floor: each row formatted by csvrows.c into a 1 MiB buffer, written
  to the file whenever the next line might not fit (the same bytes per value).
* ``parquet``: as ``csv`` to a Parquet file; no C loop writes Parquet without Arrow: the floor
  records into its array and writes it with pyarrow's ParquetWriter in the row groups cosim
  writes (`cosim.record.observers.rows_per_chunk`), as `cosim.record.observers.ParquetSink` does.
* ``time only``: nothing but ``time`` in memory (cosim ``keep=[]``, no file; the floor records
  nothing): what the step costs without recording.

Time: CPU time (``time.process_time``, every thread) of what recording takes part in: cosim's
`Recorder` set-up, `Execution.run` (the stepping loop and its flushes), `Recorder.close` and the
result array; the floor's loop (with its array's pages touched, its writes) and its Parquet
writing.  All eight in one process per size, interleaved (who goes first alternating between
rounds), best of ``--repeat`` (the machine is shared: the best is the least disturbed); ratios
cosim / floor.

Memory: each (way, who) in a fresh process, its peak resident memory (``VmHWM``, reset through
``/proc/self/clear_refs`` just before recording begins: after the FMUs are instantiated) minus its
resident memory then, against the bytes of the samples (rows x columns x 8); pyarrow, which
the files may use, is imported before.  ``--baseline TREE``
also runs cosim from another checkout (its kernel built: ``python setup.py build_ext --inplace``)
in processes of their own, with their own floor runs, for the figures before.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WAYS = ("memory", "csv", "parquet", "time only")
STEP = 1e-3


def _child_path(tree: str | None) -> None:
    """sys.path for a child: ``tree`` (or this one) first, then tests/ and benchmarks/ of this tree."""
    sys.path[:0] = [tree or str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]


# --------------------------------------------------------------------------- in a child process

def _hwm_reset() -> int:
    """Reset the peak resident memory to the current one; the current one (bytes)."""
    Path("/proc/self/clear_refs").write_text("5")
    return _status("VmRSS")


def _status(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024
    raise KeyError(key)


class Meter:
    """CPU seconds spent in the functions wrapped (exclusive of nesting: outermost calls only);
    ``on_start``: called before the first wrapped call of a measurement (the memory reset)."""

    def __init__(self):
        self.seconds, self.depth, self.on_start = 0.0, 0, None

    def wrap(self, function):
        def timed(*args, **kwargs):
            if self.depth == 0 and self.on_start is not None:
                self.on_start()
                self.on_start = None
            self.depth += 1
            began = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                self.depth -= 1
                if self.depth == 0:
                    self.seconds += time.process_time() - began
        return timed


def _install(meter: Meter) -> None:
    from cosim.record.observers import MemorySink, Recorder
    from cosim.run.execution import Execution

    for owner, name in ((Recorder, "__init__"), (Execution, "run"), (Recorder, "close"), (MemorySink, "array")):
        setattr(owner, name, meter.wrap(getattr(owner, name)))


def cosim_once(folder: Path, way: str, out: Path, meter: Meter) -> tuple[float, int]:
    """CPU seconds of cosim's recording in one run recording ``way``, and the samples' bytes."""
    import cosim.run.simulation

    output = {"csv": out / "r.csv", "parquet": out / "r.parquet"}.get(way)
    keep = None if way == "memory" else []
    prepared = cosim.prepare(folder, use_providers=False)
    try:
        meter.seconds = 0.0
        outcome = cosim.run.simulation.run(prepared, output=output, keep=keep, kernel="native")
        rows, columns = outcome.samples, 1 + len(prepared.plan.columns)
    finally:
        prepared.close()
    if outcome.status != "completed":
        raise RuntimeError(f"cosim: {outcome.status} {outcome.message}")
    for written in out.glob("r.*"):
        written.unlink()
    return meter.seconds, rows * columns * 8


def floor_once(library: Path, spec: dict, way: str, out: Path, on_start=None) -> tuple[float, int]:
    """CPU seconds of the C floor recording ``way`` (and pyarrow's writing, for Parquet), and the
    samples' bytes."""
    from c_floor import run_c_floor

    stop = spec["steps"] * STEP
    args = (library, spec["fmus"], spec["outputs"], [], [], 0.0, stop, STEP)
    clock = time.process_time
    if on_start is not None:   # the memory reset before the loop: just after instantiation
        def clock() -> float:
            nonlocal on_start
            if on_start is not None:
                on_start()
                on_start = None
            return time.process_time()
    if way == "csv":
        seconds, _ = run_c_floor(*args, csv=out / "r.csv", clock=clock)
    elif way == "time only":
        seconds, _ = run_c_floor(*args, record=False, clock=clock)
    else:
        seconds, rows = run_c_floor(*args, clock=clock)
        if way == "parquet":
            seconds += _parquet(rows, out / "r.parquet")
    for written in out.glob("r.*"):
        written.unlink()
    return seconds, (spec["steps"] + 1) * spec["width"] * 8


def _parquet(rows, path: Path) -> float:
    """CPU seconds of writing ``rows`` (a structured array) as `cosim.record.observers.ParquetSink`
    writes chunks: row groups of `rows_per_chunk` rows, no dictionary encoding."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq
    try:
        from cosim.record.observers import rows_per_chunk
    except ImportError:   # a tree before it (--baseline): chunks of CHUNK_ROWS
        from cosim.record.observers import CHUNK_ROWS

        def rows_per_chunk(columns: int, rows: int) -> int:
            return CHUNK_ROWS

    began = time.process_time()
    names = list(rows.dtype.names)
    plain = rows.view(np.float64).reshape(len(rows), len(names))
    schema = pa.schema([(n, pa.float64()) for n in names])
    block = rows_per_chunk(len(names), len(rows))
    with pq.ParquetWriter(path, schema, use_dictionary=False) as writer:
        for start in range(0, len(rows), block):
            columns = np.ascontiguousarray(plain[start:start + block].T)
            writer.write_table(pa.Table.from_arrays(list(columns), schema=schema))
    return time.process_time() - began


def _spec(folder: Path, steps: int) -> dict:
    """The floor's description of the system at ``folder``."""
    import cosim

    with cosim.prepare(folder, use_providers=False) as prepared:
        plan = prepared.plan
        return {"fmus": [(c, str(d.path), {}) for c, d in plan.fmus.items()],
                "outputs": {c: [v.name for v in plan.outputs[c]] for c in plan.fmus},
                "steps": steps, "width": 1 + len(plan.columns)}


def child_times(args: argparse.Namespace) -> dict:
    """Every way by both, interleaved, best of ``--repeat`` (CPU seconds)."""
    from c_floor import compile_floor

    meter = Meter()
    _install(meter)
    out = Path(args.out)
    spec = _spec(Path(args.folder), args.child_steps)
    library = compile_floor(out)
    best: dict[str, float] = {}
    for round_ in range(args.repeat):
        for way in WAYS:
            # who goes first alternates: a run allocating right after the other freed its memory
            # (64 MB of rows at N = 1000) pays less for its pages
            for who in ("cosim", "floor") if round_ % 2 == 0 else ("floor", "cosim"):
                seconds, _ = (cosim_once(Path(args.folder), way, out, meter) if who == "cosim"
                              else floor_once(library, spec, way, out))
                key = f"{who} {way}"
                best[key] = min(best.get(key, float("inf")), seconds)
    return best


def child_memory(args: argparse.Namespace) -> dict:
    """One run of one way by one, its peak resident memory above the one when recording began."""
    out = Path(args.out)
    base = {}
    if args.way != "memory":   # a library import is not recorded samples: imported before the reset
        import pyarrow.csv  # noqa: F401
        import pyarrow.parquet  # noqa: F401

    def reset() -> None:
        base["rss"] = _hwm_reset()

    if args.who == "cosim":
        meter = Meter()
        _install(meter)
        meter.on_start = reset
        _, samples = cosim_once(Path(args.folder), args.way, out, meter)
    else:
        from c_floor import compile_floor
        spec = _spec(Path(args.folder), args.child_steps)
        _, samples = floor_once(compile_floor(out), spec, args.way, out, on_start=reset)
    return {"peak": _status("VmHWM") - base["rss"], "samples": samples}


# --------------------------------------------------------------------------- the parent

def spawn(mode: str, folder: Path, steps: int, out: Path, tree: str | None, **extra) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    argv = [sys.executable, __file__, "--child", mode, "--folder", str(folder), "--child-steps", str(steps),
            "--out", str(out)] + (["--tree", tree] if tree else [])
    for key, value in extra.items():
        argv += [f"--{key.replace('_', '-')}", str(value)]
    done = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    if not lines:
        raise RuntimeError(f"{mode} child failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT "):])


def measure(sizes: list[int], steps: list[int], repeat: int, baseline: str | None, folder: Path) -> dict:
    sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]
    from native_systems import FAMILIES, build_family, native_system, write_native_system

    fmus = build_family("c", folder / "fmus")
    trees = {"now": None} | ({"before": baseline} if baseline else {})
    found: dict = {}
    for n, count in zip(sizes, steps):
        system = write_native_system(native_system(FAMILIES["c"], "independent", n), fmus, folder / f"sys{n}",
                                     count * STEP, STEP)
        for name, tree in trees.items():
            print(f"N = {n}, {name}: times", file=sys.stderr, flush=True)
            found[(name, n, "times")] = spawn("times", system, count, folder / "out", tree, repeat=repeat)
            for way in WAYS:
                for who in ("cosim", "floor"):
                    print(f"N = {n}, {name}: memory of {who} {way}", file=sys.stderr, flush=True)
                    found[(name, n, who, way)] = spawn("memory", system, count, folder / "out", tree, who=who,
                                                       way=way)
    return found


def report(found: dict, sizes: list[int], steps: list[int], trees: list[str], markdown: bool) -> str:
    header = ["N", "steps", "recording", "tree", "floor CPU ms", "cosim CPU ms", "cosim / floor",
              "samples MiB", "floor peak MiB", "cosim peak MiB", "cosim peak / samples"]
    rows = []
    for n, count in zip(sizes, steps):
        for tree in trees:
            times = found[(tree, n, "times")]
            for way in WAYS:
                floor, mine = times[f"floor {way}"], times[f"cosim {way}"]
                memory = found[(tree, n, "cosim", way)]
                samples = memory["samples"] / 2**20
                rows.append([str(n), str(count), way, tree, f"{1e3 * floor:.1f}", f"{1e3 * mine:.1f}",
                             f"{mine / floor:.2f}", f"{samples:.1f}",
                             f"{found[(tree, n, 'floor', way)]['peak'] / 2**20:.1f}",
                             f"{memory['peak'] / 2**20:.1f}", f"{memory['peak'] / memory['samples']:.2f}"])
    if markdown:
        return "\n".join(["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                         + ["| " + " | ".join(r) + " |" for r in rows])
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(line, widths)) for line in [header] + rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 1000])
    parser.add_argument("--steps", type=int, nargs="+", default=[20000, 4000], help="steps, one per size")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--baseline", metavar="TREE", help="also run cosim from this tree (its figures before)")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--child", choices=["times", "memory"], help=argparse.SUPPRESS)
    parser.add_argument("--folder", help=argparse.SUPPRESS)
    parser.add_argument("--child-steps", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--tree", help=argparse.SUPPRESS)
    parser.add_argument("--who", help=argparse.SUPPRESS)
    parser.add_argument("--way", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child_path(args.tree)
        result = child_times(args) if args.child == "times" else child_memory(args)
        print("RESULT " + json.dumps(result))
        return
    if len(args.steps) != len(args.sizes):
        parser.error("give one --steps per size")
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-recording-") as tmp:
        found = measure(args.sizes, args.steps, args.repeat, args.baseline, Path(tmp))
    print(f"independent N (C FMUs), steps of {STEP * 1e3:g} ms; CPU time best of {args.repeat} interleaved; "
          f"load average {load:.1f} before, {os.getloadavg()[0]:.1f} after, {os.cpu_count()} cores")
    print(report(found, args.sizes, args.steps, ["now"] + (["before"] if args.baseline else []), args.markdown))


if __name__ == "__main__":
    main()
