"""Master overhead: cosim vs fmpy.ssp vs libcosim vs a raw-ctypes floor, in one process.

    python benchmarks/bench_master.py [--steps 50000] [--repeat 3]

Runs the packed ``pid_fopdt`` scenario (PID + FOPDT + two Step sources, every connector
recorded) for ``--steps`` steps of 0.1 s in each master, and a wider system: five
PID/FOPDT loops in a cascade (10 FMUs, each in 3 or more connections).  Each number is
the best of ``--repeat`` runs of the stepping loop alone (loading and unzipping excluded
for every master).  The FMUs are the same pythonfmu builds for all; their Python
``do_step`` dominates the floor.  Prints µs per step and the ratios docs/performance.md reports.

fmpy.ssp ignores parameter bindings (docs/peers.md), so it runs with FMU defaults; the
FMI calls per step are the same, which is what is timed.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]  # the root first: tests/cosim would shadow cosim

import cosim  # noqa: E402
from cosim.cli import main as cosim_main  # noqa: E402
from floor import run_floor  # noqa: E402
from peers import run_fmpy_ssp, run_libcosim  # noqa: E402

STEP = 0.1


def cascade_ssd(loops: int = 5) -> str:
    """Five PID/FOPDT loops; loop i's output is loop i+1's setpoint and loop i's error
    disturbs plant i+1 (so each FMU has 3 or more connections)."""
    ns = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
          'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
          'xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"')
    comps, conns = [], []
    for i in range(loops):
        comps.append(f'''<ssd:Component name="pid{i}" source="resources/PID.fmu"><ssd:Connectors>
  <ssd:Connector name="r" kind="input"><ssc:Real/></ssd:Connector>
  <ssd:Connector name="y" kind="input"><ssc:Real/></ssd:Connector>
  <ssd:Connector name="u" kind="output"><ssc:Real/></ssd:Connector>
  <ssd:Connector name="e" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>
<ssd:Component name="plant{i}" source="resources/FOPDT.fmu"><ssd:Connectors>
  <ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>
  <ssd:Connector name="d" kind="input"><ssc:Real/></ssd:Connector>
  <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>''')
        conns += [f'<ssd:Connection startElement="plant{i}" startConnector="y" endElement="pid{i}" endConnector="y"/>',
                  f'<ssd:Connection startElement="pid{i}" startConnector="u" endElement="plant{i}" endConnector="u"/>']
        up = (i - 1) % loops
        conns += [f'<ssd:Connection startElement="plant{up}" startConnector="y" endElement="pid{i}" endConnector="r"/>',
                  f'<ssd:Connection startElement="pid{up}" startConnector="e" endElement="plant{i}" endConnector="d"/>']
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {ns} version="1.0" '
            f'name="cascade"><ssd:System name="cascade"><ssd:Elements>{"".join(comps)}</ssd:Elements>'
            f'<ssd:Connections>{"".join(conns)}</ssd:Connections></ssd:System>'
            f'<ssd:DefaultExperiment startTime="0" stopTime="100"><ssd:Annotations>'
            f'<ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm>'
            f'<osp:FixedStepAlgorithm baseStepSize="{STEP}"/></osp:Algorithm></ssc:Annotation>'
            f'</ssd:Annotations></ssd:DefaultExperiment></ssd:SystemStructureDescription>\n')


def floor_spec(plan):
    """The FMUs, parameters and connections of a prepared system, for the floor."""
    params: dict[str, dict] = {c: {} for c in plan.fmus}
    for sv in plan.start_values:
        params[sv.component][sv.variable.name] = float(sv.value)
    fmus = [(c, str(d.path), params[c]) for c, d in plan.fmus.items()]
    conns = [(r.src, r.src_var.name, r.dst, r.dst_var.name) for r in plan.routes]
    signals = [f"{c}.{v.name}" for c in plan.fmus for v in plan.outputs[c] + plan.inputs[c]]
    return fmus, conns, signals


def time_cosim(ssp: str | Path, stop: float) -> float:
    prepared = cosim.prepare(ssp, stop_time=stop, use_providers=False)
    try:
        _, meta = cosim.run.simulation.run(prepared)
    finally:
        prepared.close()
    return meta["loop_seconds"]


def measure(ssp: str, steps: int, repeat: int) -> dict[str, float]:
    stop = steps * STEP
    prepared = cosim.prepare(ssp, use_providers=False)   # keeps the archive's FMUs extracted
    fmus, conns, signals = floor_spec(prepared.plan)
    best: dict[str, float] = {}

    def keep(name: str, seconds: float) -> None:
        best[name] = min(best.get(name, float("inf")), seconds / steps * 1e6)

    for _ in range(repeat):
        keep("floor", run_floor(fmus, conns, 0.0, stop, STEP, signals)[0])
        keep("cosim", time_cosim(ssp, stop))
        timing: dict = {}
        run_fmpy_ssp(ssp, 0.0, stop, STEP, signals, timing=timing)
        keep("fmpy.ssp", timing["loop_seconds"])
        timing = {}
        run_libcosim(ssp, 0.0, stop, STEP, signals, timing=timing)
        keep("libcosim", timing["loop_seconds"])
    prepared.close()
    return best


def report(title: str, us: dict[str, float]) -> None:
    print(f"\n{title}")
    for name, value in us.items():
        print(f"  {name:9} {value:8.2f} µs/step")
    print(f"  cosim overhead above the floor: {100 * (us['cosim'] / us['floor'] - 1):5.1f} %")
    print(f"  cosim / fmpy.ssp: {us['cosim'] / us['fmpy.ssp']:.2f}    cosim / libcosim: "
          f"{us['cosim'] / us['libcosim']:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        loop = str(Path(tmp) / "pid_fopdt.ssp")
        cosim_main(["pack", str(ROOT / "ssp" / "pid_fopdt"), "-o", loop])
        wide_dir = Path(tmp) / "cascade"
        wide_dir.mkdir()
        (wide_dir / "SystemStructure.ssd").write_text(cascade_ssd())
        wide = str(Path(tmp) / "cascade.ssp")
        cosim_main(["pack", str(wide_dir), "-o", wide])
        report(f"pid_fopdt (2 FMUs in the loop + 2 sources), {args.steps} steps", measure(loop, args.steps, args.repeat))
        report(f"cascade (10 FMUs, 20 connections), {args.steps // 5} steps",
               measure(wide, args.steps // 5, args.repeat))


if __name__ == "__main__":
    main()
