"""Two source trees of the master, the same systems: the stepping loop's time per step, old against new.

    python benchmarks/bench_trees.py OLD_TREE [NEW_TREE] [--steps 20000] [--repeat 5] [--sizes 1 10]

A refactor of the master must not slow its loop; this runs each case on both trees (a tree is a
checkout of the repository with its kernel library built: ``python setup.py build_ext --inplace``
there; NEW_TREE defaults to this one), each run in a fresh process whose ``sys.path`` starts with
that tree, the trees alternating within every round, and keeps the best of ``--repeat`` runs of
each (the machine is shared: the best is the run least disturbed).  Cases: the C family of
benchmarks/native_systems.py (no FMU runs Python), ``independent`` and ``chained`` systems of
``--sizes`` FMUs, and a chain whose connections carry an ``ssc:LinearTransformation`` (routes with
a factor and offset), on the compiled loop and on the Python interpreter.  Printed: µs per step on
each tree (metadata ``loop_seconds`` / steps: wall time) and the ratio new/old, and the same of the
loop's CPU time (``time.thread_time`` around ``Stepping.run``, on both trees: the share of a loaded
machine a run gets does not enter it).

Issue 40 (96f2739 against the stages, transformations, frozen plan, compile/link: 194f68c), best of
7, load 4.2-4.4, CPU µs per step old -> new: compiled loop independent 1 0.076 -> 0.074 (0.98x),
independent 10 0.340 -> 0.339 (1.00x), chained 10 0.409 -> 0.413 (1.01x), chained 10 with a
LinearTransformation on every connection 0.426 -> 0.433 (1.02x); Python interpreter 0.90x, 1.03x,
0.98x, 0.94x.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "benchmarks")]

from native_systems import FAMILIES, build_family, native_system, write_native_system  # noqa: E402

STEP = 1e-3
KERNELS = ("native", "python")

#: run in a fresh process with the tree first on sys.path: prints the loop's seconds
RUNNER = """
import json, sys
import cosim
assert cosim.__file__.startswith(sys.argv[4]), (cosim.__file__, sys.argv[4])
import time
try:   # the tree before issue 40's stages; after it, cosim.run.simulation
    from cosim.simulation import run
    from cosim.stepping import Stepping
except ImportError:
    from cosim.run.simulation import run
    from cosim.run.stepping import Stepping
cpu = []
stepping = Stepping.run


def timed(self, *args, **kw):   # the stepping loop's CPU time (this thread's: the compiled loop runs on it)
    started = time.thread_time()
    try:
        return stepping(self, *args, **kw)
    finally:
        cpu.append(time.thread_time() - started)


Stepping.run = timed
prepared = cosim.prepare(sys.argv[1], stop_time=float(sys.argv[2]), use_providers=False)
with prepared:
    outcome = run(prepared, kernel=sys.argv[3], journal=False)
meta = outcome.metadata
assert meta["kernel"] == sys.argv[3], meta.get("kernel_reason")
print(json.dumps({"loop": meta["loop_seconds"], "cpu": cpu[0], "last": float(outcome.result[-1][1])}))
"""


def cases(folder: Path, sizes: list[int], stop: float) -> dict[str, Path]:
    """The SSP folders of every case, by label."""
    family = FAMILIES["c"]
    fmus = build_family("c", folder / "fmus")
    out = {}
    for n in sizes:
        for topology in ("independent", "chained"):
            if topology == "chained" and n < 2:
                continue
            system = native_system(family, topology, n)
            out[f"{topology} {n}"] = write_native_system(system, fmus, folder / f"{topology}_{n}", stop, STEP)
        if n >= 2:
            ssd = write_native_system(native_system(family, "chained", n), fmus, folder / f"linear_{n}", stop, STEP)
            file = ssd / "SystemStructure.ssd"
            file.write_text(re.sub(r'(<ssd:Connection [^>]*?)/>', r'\1><ssc:LinearTransformation factor="1.5" '
                                  r'offset="0.25"/></ssd:Connection>', file.read_text()))
            out[f"chained {n}, factor+offset"] = ssd
    return out


def run(tree: Path, ssd: Path, stop: float, kernel: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, "-c", RUNNER, str(ssd), repr(stop), kernel, str(tree)], env=env, cwd=tree,
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise RuntimeError(f"{tree}: {done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path, nargs="?", default=ROOT)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 10])
    args = parser.parse_args()
    stop = args.steps * STEP
    trees = {"old": args.old.resolve(), "new": args.new.resolve()}
    best: dict[tuple[str, str, str], float] = {}
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        systems = cases(Path(tmp), args.sizes, stop)
        for round_ in range(args.repeat):
            print(f"round {round_ + 1}/{args.repeat}", file=sys.stderr, flush=True)
            for label, ssd in systems.items():
                for kernel in KERNELS:
                    lasts = set()
                    for which in (("old", "new") if round_ % 2 == 0 else ("new", "old")):
                        got = run(trees[which], ssd, stop, kernel)
                        lasts.add(got["last"])
                        for measure in ("loop", "cpu"):
                            key = (label, kernel, which, measure)
                            best[key] = min(best.get(key, float("inf")), got[measure] / args.steps * 1e6)
                    if len(lasts) != 1:
                        raise RuntimeError(f"{label}, {kernel}: the trees' results differ: {lasts}")
    after = os.getloadavg()
    print(f"{args.steps} steps of {STEP * 1e3:g} ms, best of {args.repeat} (trees alternating), µs per step; "
          f"old {trees['old']}, new {trees['new']}; load average {load[0]:.2f} before, {after[0]:.2f} after")
    print(f"{'case':32} {'kernel':7} {'old':>8} {'new':>8} {'new/old':>8}   CPU: {'old':>8} {'new':>8} {'new/old':>8}")
    for label in systems:
        for kernel in KERNELS:
            old, new = best[(label, kernel, "old", "loop")], best[(label, kernel, "new", "loop")]
            old_cpu, new_cpu = best[(label, kernel, "old", "cpu")], best[(label, kernel, "new", "cpu")]
            print(f"{label:32} {kernel:7} {old:8.3f} {new:8.3f} {new / old:8.2f}        {old_cpu:8.3f} {new_cpu:8.3f} "
                  f"{new_cpu / old_cpu:8.2f}")


if __name__ == "__main__":
    main()
