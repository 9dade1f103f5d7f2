"""The fixed cost of one run, by stage, next to libcosim and fmpy (issue 28).

    python benchmarks/bench_fixed_cost.py [--repeat 5] [--warm 5] [--systems native pid_fopdt] [--profile]

A run of two communication steps, so what is measured is what every run pays whatever its
length: reading the SSD, checking it against the FMUs, unpacking, loading the libraries,
instantiating, initialising, setting up the recording, writing the results (in memory here)
and freeing.  Systems:

* ``native``: 10 C FMUs (benchmarks/native_systems.py, ``chained 10``: a Van der Pol oscillator
  then 9 direct-feedthrough ``Lag`` blocks), steps of 1 ms;
* ``pid_fopdt``: ssp/pid_fopdt, 4 pythonfmu FMUs of ours (the FMU loader starts Python's greyfmu
  numerics in the process), its default step.

Each number is the best of ``--repeat`` fresh processes (the ``import cosim`` not counted) of
the **first** run in the process, and, in the process that ran it, the best of ``--warm`` more
runs (``warm``: what a sweep or a test session pays per run).  cosim is measured with an empty
FMU cache (``COSIM_FMU_CACHE`` a new folder: every FMU unpacked) and with the cache populated
(``unpacked``), through `cosim.simulate` itself, and (``instances reused``) as a sweep worker
runs: the scenario read once, the instances reset and kept across runs (`cosim.run.instances.reuse`;
a warm run's ``free`` is then terminate and fmi2Reset): each stage is the time spent in the function
that does it (exclusive of the stages it calls, timed by wrapping it):

=================  ==========================================================================
read               `cosim.read.ssp.load`: the SSD (and SSVs), schema-validated
locate             `cosim.read.resources.locate_fmus`
check/plan         `cosim.plan.build.build_plan`: the FMUs checked (`cosim.read.loadable`), their
                   model descriptions read (`cosim.read.description`), the plan made
unpack             `cosim.run.instances.Unzipped`: the FMU cache entry looked up or made
load               `cosim.run.instances.open_instance`: the library loaded (dlopen) by fmpy
instantiate        fmi2Instantiate (the instance classes' ``instantiate``)
exec set-up        `cosim.run.execution.Execution`: buffers, routing, the compiled kernel's calls
record set-up      `cosim.record.observers.Recorder`
initialise         `Execution.initialize`: setup, start values, initialisation mode
write              `Recorder.close`: the result array and metadata
free               `Execution.close`: fmi2FreeInstance
other              the rest of `cosim.simulate` (the grid, metadata, the lock)
steps              `Execution.run`: the two steps (not a fixed cost)
=================  ==========================================================================

Peers, on the same systems: libcosim 0.11.2 (libcosimpy 0.0.6; ``create``: reading, unpacking,
loading and instantiating, one C call; ``init+steps``: its first ``step(2)``, where it
initialises; ``free``: the execution destroyed) and ``fmpy.ssp.simulate_ssp`` (fmpy 0.3.32,
on the packed ``.ssp``: one call, which unpacks everything each time).  ``--profile`` prints
the cProfile of a first cosim run with the FMUs unpacked.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

STAGES = ("read", "locate", "describe", "plan", "unpack", "load", "instantiate", "compile", "link",
          "record set-up", "initialise", "write", "free", "other")
NATIVE_STEP = 1e-3


# --------------------------------------------------------------------------- in the child process

class Timers:
    """Exclusive time per stage: a timed function called inside another counts for its own stage only."""

    def __init__(self):
        self.totals: dict[str, float] = {}
        self._stack: list[list] = []

    def wrap(self, stage: str, function):
        def timed(*args, **kwargs):
            frame = [time.process_time(), 0.0]
            self._stack.append(frame)
            try:
                return function(*args, **kwargs)
            finally:
                self._stack.pop()
                elapsed = time.process_time() - frame[0]
                self.totals[stage] = self.totals.get(stage, 0.0) + elapsed - frame[1]
                if self._stack:
                    self._stack[-1][1] += elapsed
        return timed


def install(timers: Timers) -> None:
    """Wrap the functions of each stage (the table of the module docstring); a function a tree
    does not have (an older one, ``--tree``) is left out."""
    import cosim.plan.prepare
    import cosim.read.ssp
    import cosim.run.execution
    import cosim.run.simulation
    from cosim.run.execution import Execution
    from cosim.run.instances import FMI2Instance, FMI3Instance, ME3Instance, MEInstance, Unzipped
    from cosim.record.observers import Recorder

    for module, name, stage in ((cosim.read.ssp, "load", "read"), (cosim.plan.prepare, "locate_fmus", "locate"),
                                (cosim.plan.prepare, "describe_fmus", "describe"),
                                (cosim.plan.prepare, "build_plan", "plan"),
                                (cosim.run.execution, "open_instance", "load"),
                                (cosim.run.simulation, "compile_program", "compile"),
                                (Unzipped, "__call__", "unpack"), (Execution, "link", "link"),
                                (Recorder, "__init__", "record set-up"), (Execution, "initialize", "initialise"),
                                (Execution, "run", "steps"), (Recorder, "close", "write"), (Execution, "close", "free")):
        if hasattr(module, name):
            setattr(module, name, timers.wrap(stage, getattr(module, name)))
    for cls in (FMI2Instance, FMI3Instance, MEInstance, ME3Instance):
        if "instantiate" in cls.__dict__:
            setattr(cls, "instantiate", timers.wrap("instantiate", cls.__dict__["instantiate"]))


def cosim_runs(path: str, stop: float, step: float, warm: int, profile: bool) -> dict:
    import cosim

    timers = Timers()
    install(timers)
    simulate = timers.wrap("total", cosim.simulate)

    def once() -> dict[str, float]:
        timers.totals = {}
        simulate(path, stop_time=stop, step_size=step)
        stages = dict(timers.totals)
        stages["other"] = stages.pop("total")
        return stages

    if profile:
        import cProfile
        import pstats
        profiler = cProfile.Profile()
        profiler.enable()
        first = once()
        profiler.disable()
        pstats.Stats(profiler, stream=sys.stderr).sort_stats("cumulative").print_stats(30)
    else:
        first = once()
    warm_runs = [once() for _ in range(warm)]
    return {"first": first, "warm": min(warm_runs, key=fixed) if warm_runs else first}


def reused_runs(path: str, stop: float, step: float, warm: int) -> dict:
    """As `cosim_runs`, but as a sweep worker runs (`cosim.sweep.worker`): the scenario read and
    located once, each run's plan made from it, the instances kept in an `InstancePool` (a warm
    run's "free" is terminate + fmi2Reset, its "instantiate" nothing)."""
    import cosim.plan.prepare
    from cosim.run.instances.reuse import InstancePool
    from cosim.run.simulation import run

    timers = Timers()
    install(timers)
    pool, kept = InstancePool(), []

    def simulate() -> None:
        if not kept:
            kept.append(cosim.plan.prepare.load_scenario(path))
        run(cosim.plan.prepare.prepare_scenario(kept[0], stop_time=stop, step_size=step), pool=pool)
    timed = timers.wrap("total", simulate)

    def once() -> dict[str, float]:
        timers.totals = {}
        timed()
        stages = dict(timers.totals)
        stages["other"] = stages.pop("total")
        return stages

    first = once()
    warm_runs = [once() for _ in range(warm)]
    return {"first": first, "warm": min(warm_runs, key=fixed) if warm_runs else first}


def libcosim_runs(ssp: str, stop: float, step: float, warm: int) -> dict:
    import ctypes

    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy._internal import get_last_error_message, libcosimc, wrap_function

    log_output_level(CosimLogLevel.ERROR)
    create = wrap_function(lib=libcosimc(), funcname="cosim_ssp_fixed_step_execution_create",
                           argtypes=[ctypes.c_char_p, ctypes.c_bool, ctypes.c_int64, ctypes.c_int64],
                           restype=ctypes.POINTER(CosimExecution))

    def once() -> dict[str, float]:
        t0 = time.process_time()
        ptr = create(str(Path(ssp).resolve()).encode(), True, 0, round(step * 1e9))
        if not ptr:
            raise RuntimeError(f"libcosim could not load {ssp}: {get_last_error_message()}")
        execution = CosimExecution(CosimExecution._CosimExecution__create_key, ptr)
        t1 = time.process_time()
        if not execution.step(round(stop / step)):
            raise RuntimeError(f"libcosim step failed: {get_last_error_message()}")
        t2 = time.process_time()
        del execution
        t3 = time.process_time()
        return {"create": t1 - t0, "init+steps": t2 - t1, "free": t3 - t2}

    first = once()
    warm_runs = [once() for _ in range(warm)]
    return {"first": first, "warm": min(warm_runs, key=fixed) if warm_runs else first}


def fmpy_runs(ssp: str, stop: float, step: float, warm: int) -> dict:
    from fmpy.ssp.simulation import simulate_ssp

    def once() -> dict[str, float]:
        t0 = time.process_time()
        simulate_ssp(ssp, stop_time=stop, step_size=step)
        return {"simulate_ssp": time.process_time() - t0}

    first = once()
    warm_runs = [once() for _ in range(warm)]
    return {"first": first, "warm": min(warm_runs, key=fixed) if warm_runs else first}


def fixed(stages: dict[str, float]) -> float:
    """A run's fixed cost: all but the steps."""
    return sum(v for k, v in stages.items() if k != "steps")


def child(args: argparse.Namespace) -> None:
    if args.tree:   # another tree's cosim (--baseline): first on sys.path, before anything imports cosim
        sys.path.insert(0, args.tree)
    runner = {"cosim": lambda: cosim_runs(args.path, args.stop, args.step, args.warm, args.profile),
              "cosim-reused": lambda: reused_runs(args.path, args.stop, args.step, args.warm),
              "libcosim": lambda: libcosim_runs(args.path, args.stop, args.step, args.warm),
              "fmpy": lambda: fmpy_runs(args.path, args.stop, args.step, args.warm)}[args.child]
    try:
        result = runner()
    except Exception as e:  # a peer that cannot run the system: the reason instead of a number
        result = {"error": f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"}
    print("RESULT " + json.dumps(result))


# --------------------------------------------------------------------------- the parent

def systems(folder: Path) -> dict[str, dict]:
    """Each system: the folder cosim runs, the packed .ssp the peers run, stop and step."""
    from cosim.read import ssp as cosim_ssp
    from cosim.cli import main as cosim_main
    from native_systems import FAMILIES, build_family, native_system, write_native_system

    fmus = build_family("c", folder / "fmus")
    native = write_native_system(native_system(FAMILIES["c"], "chained", 10), fmus, folder / "native",
                                 2 * NATIVE_STEP, NATIVE_STEP)
    pid = ROOT / "ssp" / "pid_fopdt"
    step = cosim_ssp.load(pid).step_size
    out = {"native": {"path": native, "stop": 2 * NATIVE_STEP, "step": NATIVE_STEP},
           "pid_fopdt": {"path": pid, "stop": 2 * step, "step": step}}
    for name, system in out.items():
        packed = folder / f"{name}.ssp"
        if cosim_main(["pack", str(system["path"]), "-o", str(packed)]) != 0:
            raise RuntimeError(f"cosim pack failed on {system['path']}")
        system["ssp"] = packed
    return out


def spawn(kind: str, path: Path, stop: float, step: float, warm: int, env: dict, profile: bool = False,
          tree: str | None = None) -> dict:
    argv = [sys.executable, __file__, "--child", kind, "--path", str(path), "--stop", repr(stop),
            "--step", repr(step), "--warm", str(warm)] + (["--profile"] if profile else []) \
        + (["--tree", tree] if tree else [])
    done = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=ROOT)
    if profile:
        print(done.stderr)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    if not lines:
        return {"error": f"exit {done.returncode}: {done.stderr.strip().splitlines()[-1:] or ''}"}
    return json.loads(lines[-1][len("RESULT "):])


def best(results: list[dict]) -> dict:
    good = [r for r in results if "error" not in r]
    if not good:
        return results[0]
    return {"first": min((r["first"] for r in good), key=fixed), "warm": min((r["warm"] for r in good), key=fixed)}


def measure(system: dict, repeat: int, warm: int, folder: Path, profile: bool,
            baseline: str | None = None) -> dict[str, dict]:
    cache = folder / "cache"
    base = dict(os.environ, COSIM_FMU_CACHE=str(cache))
    cases: dict[str, list] = {"cosim, FMUs not unpacked": [], "cosim, FMUs unpacked": [],
                              "cosim, instances reused": [], "libcosim": [], "fmpy": []}
    if baseline:
        cases["cosim, before, FMUs unpacked"] = []
    spawn("cosim", system["path"], system["stop"], system["step"], 0, base)   # the cache populated
    for k in range(repeat):
        if baseline:
            cases["cosim, before, FMUs unpacked"].append(
                spawn("cosim", system["path"], system["stop"], system["step"], warm, base, tree=baseline))
        empty = folder / f"empty{k}-{time.monotonic_ns()}"
        cases["cosim, FMUs not unpacked"].append(
            spawn("cosim", system["path"], system["stop"], system["step"], warm, dict(base, COSIM_FMU_CACHE=str(empty))))
        cases["cosim, FMUs unpacked"].append(
            spawn("cosim", system["path"], system["stop"], system["step"], warm, base))
        cases["cosim, instances reused"].append(
            spawn("cosim-reused", system["path"], system["stop"], system["step"], warm, base))
        cases["libcosim"].append(spawn("libcosim", system["ssp"], system["stop"], system["step"], warm, base))
        cases["fmpy"].append(spawn("fmpy", system["ssp"], system["stop"], system["step"], warm, base))
    if profile:
        spawn("cosim", system["path"], system["stop"], system["step"], 0, base, profile=True)
    return {name: best(results) for name, results in cases.items()}


def scale(sizes: list[int], repeat: int, warm: int, folder: Path, baseline: str | None,
          libcosim_max: int) -> str:
    """The fixed cost of a 2-step run of ``chained N`` (C family) for each of ``sizes``: stages,
    CPU ms per FMU, the exponent of the growth between sizes (1: linear, 2: quadratic), libcosim's
    first run beside it; each size in fresh processes, the sizes (and trees) interleaved in every round."""
    from native_systems import FAMILIES, build_family, native_system, write_native_system
    from cosim.cli import main as cosim_main

    fmus = build_family("c", folder / "fmus")
    env = dict(os.environ, COSIM_FMU_CACHE=str(folder / "cache"))
    trees = {"now": None} | ({"before": baseline} if baseline else {})
    paths, results = {}, {}
    for n in sizes:
        paths[n] = write_native_system(native_system(FAMILIES["c"], "chained", n), fmus, folder / f"chained{n}",
                                       2 * NATIVE_STEP, NATIVE_STEP)
        packed = folder / f"chained{n}.ssp"
        if n <= libcosim_max and cosim_main(["pack", str(paths[n]), "-o", str(packed)]) != 0:
            raise RuntimeError(f"cosim pack failed on {paths[n]}")
        spawn("cosim", paths[n], 2 * NATIVE_STEP, NATIVE_STEP, 0, env)   # the cache populated
    for round_ in range(repeat):
        for n in sizes:
            print(f"round {round_ + 1}/{repeat}: N = {n}", file=sys.stderr, flush=True)
            for name, tree in trees.items():
                results.setdefault((name, n), []).append(
                    spawn("cosim", paths[n], 2 * NATIVE_STEP, NATIVE_STEP, warm, env, tree=tree))
            if n <= libcosim_max:
                results.setdefault(("libcosim", n), []).append(
                    spawn("libcosim", folder / f"chained{n}.ssp", 2 * NATIVE_STEP, NATIVE_STEP, 0, env))
    found = {key: best(runs) for key, runs in results.items()}
    lines = [f"chained N (C FMUs): fixed cost of a 2-step run, CPU ms, first run of a fresh process "
             f"(FMUs unpacked), best of {repeat}"]
    for name in trees:
        lines.append(f"\n  cosim {name}:")
        lines.append(f"  {'stage':<14}" + "".join(f"{'N = ' + str(n):>12}" for n in sizes))
        for stage in STAGES:
            lines.append(f"  {stage:<14}" + "".join(
                f"{1e3 * found[(name, n)]['first'].get(stage, 0.0):>12.2f}" if "error" not in found[(name, n)]
                else f"{'—':>12}" for n in sizes))
        totals = {n: fixed(found[(name, n)]["first"]) for n in sizes if "error" not in found[(name, n)]}
        lines.append(f"  {'= fixed':<14}" + "".join(f"{1e3 * totals[n]:>12.2f}" if n in totals else f"{'—':>12}"
                                                   for n in sizes))
        lines.append(f"  {'ms per FMU':<14}" + "".join(f"{1e3 * totals[n] / n:>12.3f}" if n in totals
                                                       else f"{'—':>12}" for n in sizes))
        lines.append(f"  {'growth exp.':<14}{'':>12}" + "".join(
            f"{math.log(totals[b] / totals[a]) / math.log(b / a):>12.2f}" if a in totals and b in totals
            else f"{'—':>12}" for a, b in zip(sizes, sizes[1:])))
        if name == "now" and "before" in trees:
            lines.append(f"  {'now / before':<14}" + "".join(
                f"{totals[n] / fixed(found[('before', n)]['first']):>12.2f}"
                if n in totals and "error" not in found[("before", n)] else f"{'—':>12}" for n in sizes))
    lines.append(f"\n  {'libcosim':<14}" + "".join(
        f"{1e3 * fixed(found[('libcosim', n)]['first']):>12.2f}" if ("libcosim", n) in found
        and "error" not in found[("libcosim", n)] else f"{'—':>12}" for n in sizes))
    lines.append(f"  {'now/libcosim':<14}" + "".join(
        f"{fixed(found[('now', n)]['first']) / fixed(found[('libcosim', n)]['first']):>12.2f}"
        if ("libcosim", n) in found and "error" not in found[("libcosim", n)] and "error" not in found[("now", n)]
        else f"{'—':>12}" for n in sizes))
    return "\n".join(lines)


def table(name: str, measured: dict[str, dict]) -> str:
    cosim_cases = [c for c in measured if c.startswith("cosim")]
    columns = [(c, w) for c in cosim_cases for w in ("first", "warm")]
    lines = [f"\n{name}: fixed cost of a 2-step run, ms (best of the fresh processes)",
             f"  {'stage':<14}" + "".join(f"{c.split(', ')[1] + ' ' + w:>24}" for c, w in columns)]

    def cell(case: str, when: str, stage: str) -> str:
        r = measured[case]
        return f"{'—':>24}" if "error" in r else f"{1e3 * r[when].get(stage, 0.0):>24.2f}"

    for stage in STAGES:
        lines.append(f"  {stage:<14}" + "".join(cell(c, w, stage) for c, w in columns))
    lines.append(f"  {'= fixed':<14}" + "".join(
        f"{'—':>24}" if "error" in measured[c] else f"{1e3 * fixed(measured[c][w]):>24.2f}" for c, w in columns))
    lines.append(f"  {'(steps)':<14}" + "".join(
        f"{'—':>24}" if "error" in measured[c] else f"{1e3 * measured[c][w].get('steps', 0.0):>24.2f}"
        for c, w in columns))
    for peer in ("libcosim", "fmpy"):
        r = measured[peer]
        if "error" in r:
            lines.append(f"  {peer}: cannot run it ({r['error']})")
            continue
        parts = ", ".join(f"{k} {1e3 * v:.2f}" for k, v in r["first"].items())
        lines.append(f"  {peer}: first {1e3 * fixed(r['first']):.2f} ms ({parts}); warm {1e3 * fixed(r['warm']):.2f} ms")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes per case (best taken)")
    parser.add_argument("--warm", type=int, default=5, help="runs after the first in each process (best taken)")
    parser.add_argument("--systems", nargs="+", default=["native", "pid_fopdt"], choices=["native", "pid_fopdt"])
    parser.add_argument("--profile", action="store_true", help="print the cProfile of a first run, FMUs unpacked")
    parser.add_argument("--scale", type=int, nargs="+", metavar="N",
                        help="the fixed cost of chained N C FMUs for each N (e.g. 10 100 1000 3000) instead")
    parser.add_argument("--libcosim-max", type=int, default=1000, help="largest N libcosim runs in --scale")
    parser.add_argument("--baseline", metavar="TREE",
                        help="also run cosim from this tree (a checkout with its kernel built), interleaved")
    parser.add_argument("--tree", help=argparse.SUPPRESS)
    parser.add_argument("--child", choices=["cosim", "cosim-reused", "libcosim", "fmpy"], help=argparse.SUPPRESS)
    parser.add_argument("--path", help=argparse.SUPPRESS)
    parser.add_argument("--stop", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--step", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return
    with tempfile.TemporaryDirectory(prefix="bench-fixed-cost-") as tmp:
        folder = Path(tmp)
        load = os.getloadavg()[0]
        if args.scale:
            print(scale(args.scale, args.repeat, args.warm, folder, args.baseline, args.libcosim_max))
        else:
            built = systems(folder)
            for name in args.systems:
                print(table(name, measure(built[name], args.repeat, args.warm, folder / name, args.profile,
                                          args.baseline)), flush=True)
        print(f"load average {load:.1f} before, {os.getloadavg()[0]:.1f} after, {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
