"""Grey predictor update cost and the grey PI FMU's per-step cost against the PI FMU.

    python benchmarks/bench_grey.py [--updates 20000] [--steps 20000] [--repeat 3]

1. ``GreyPredictor.update`` in Python for n = 4..15 (m = 1 and m = 5): µs per update
   (target: under 20 µs), best of ``--repeat``.
2. The same loop (Step → controller → FOPDT, master step = Ts = 0.1 s, so every step samples)
   in the master with the ``PID`` FMU (Td = 0) and with the ``GrayPredictivePI`` FMU
   (n = 4, m = 5): µs per master step (slope between ``--steps`` and twice as many, so FMU
   loading cancels) and the grey PI's extra cost relative to the PI FMU's own
   ``do_step`` (target: under 30 %).  The PI FMU's own time is measured by stepping it alone
   with fmpy (``doStep`` + one set and one get per step, as the master does).
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

import cosim  # noqa: E402
from greyfmu.build import build_fmus  # noqa: E402
from greyfmu.control import PID, GrayPredictivePI  # noqa: E402
from greyfmu.grey import GreyPredictor  # noqa: E402

LOOP = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="bench">
  <ssd:System name="loop"><ssd:Elements>
    <ssd:Component name="setpoint" source="resources/Step.fmu"><ssd:Connectors>
      <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>
    <ssd:Component name="controller" source="resources/{controller}.fmu"><ssd:Connectors>
      <ssd:Connector name="r" kind="input"><ssc:Real/></ssd:Connector>
      <ssd:Connector name="y" kind="input"><ssc:Real/></ssd:Connector>
      <ssd:Connector name="u" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
      <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
        <ssv:ParameterSet version="1.0" name="c"><ssv:Parameters>
          <ssv:Parameter name="Kc"><ssv:Real value="2"/></ssv:Parameter>
          <ssv:Parameter name="Ti"><ssv:Real value="20"/></ssv:Parameter>
          <ssv:Parameter name="Ts"><ssv:Real value="0.1"/></ssv:Parameter>{extra}
        </ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
    </ssd:Component>
    <ssd:Component name="plant" source="resources/FOPDT.fmu"><ssd:Connectors>
      <ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>
      <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors></ssd:Component>
  </ssd:Elements><ssd:Connections>
    <ssd:Connection startElement="setpoint" startConnector="y" endElement="controller" endConnector="r"/>
    <ssd:Connection startElement="plant" startConnector="y" endElement="controller" endConnector="y"/>
    <ssd:Connection startElement="controller" startConnector="u" endElement="plant" endConnector="u"/>
  </ssd:Connections></ssd:System>
</ssd:SystemStructureDescription>
"""
EXTRA = {"PID": '\n          <ssv:Parameter name="Td"><ssv:Real value="0"/></ssv:Parameter>',
         "GrayPredictivePI": '\n          <ssv:Parameter name="B"><ssv:Real value="2"/></ssv:Parameter>'}


def predictor_update_us(n: int, m: int, updates: int, repeat: int) -> float:
    signal = [1.0 + math.sin(0.01 * k) for k in range(updates)]
    best = math.inf
    for _ in range(repeat):
        predictor = GreyPredictor(n=n, m=m, horizon=20.0, bias=2.0, a_min=0.035)
        update = predictor.update
        start = time.perf_counter()
        for x in signal:
            update(x)
        best = min(best, time.perf_counter() - start)
    return best / updates * 1e6


def controller_step_us(controller: PID | GrayPredictivePI, steps: int, repeat: int) -> float:
    """The plain classes, in process: what the grey prediction adds to a PI sample."""
    measurements = [1.0 - math.exp(-0.001 * k) for k in range(steps)]
    best = math.inf
    for _ in range(repeat):
        controller.reset()
        start = time.perf_counter()
        for y in measurements:
            controller.step(1.0, y)
        best = min(best, time.perf_counter() - start)
    return best / steps * 1e6


def loop_step_us(folder: Path, steps: int, repeat: int) -> float:
    """Slope of the run time between ``steps`` and 2·``steps``: loading and instantiation cancel."""
    def best(count: int) -> float:
        runs = []
        for _ in range(repeat):
            start = time.perf_counter()
            cosim.simulate(folder, stop_time=count * 0.1, step_size=0.1)
            runs.append(time.perf_counter() - start)
        return min(runs)

    return (best(2 * steps) - best(steps)) / steps * 1e6


def fmu_step_us(fmu: Path, steps: int, repeat: int, parameters: dict[str, float]) -> float:
    """One FMU stepped alone by fmpy: set r, y, doStep, get u per step."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    description = read_model_description(fmu)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    unzipped = extract(fmu)
    best = math.inf
    for _ in range(repeat):
        slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                          modelIdentifier=description.coSimulation.modelIdentifier, instanceName="bench")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.setReal([refs[name] for name in parameters], list(parameters.values()))
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        inputs, outputs = [refs["r"], refs["y"]], [refs["u"]]
        start = time.perf_counter()
        for k in range(steps):
            slave.setReal(inputs, [1.0, 1.0 - math.exp(-0.001 * k)])
            slave.doStep(k * 0.1, 0.1)
            slave.getReal(outputs)
        best = min(best, time.perf_counter() - start)
        slave.terminate()
        slave.freeInstance()
    return best / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=20000)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    print("GreyPredictor.update, µs per update (target < 20):")
    for n in (4, 6, 10, 15):
        print(f"  n = {n:2d}: m = 1 {predictor_update_us(n, 1, args.updates, args.repeat):5.2f}   "
              f"m = 5 {predictor_update_us(n, 5, args.updates, args.repeat):5.2f}")

    pi_us = controller_step_us(PID(2.0, 20.0, 0.0, 0.1), args.steps, args.repeat)
    grey_us = controller_step_us(GrayPredictivePI(2.0, 20.0, 0.1, B=2.0), args.steps, args.repeat)
    print(f"Controller step in process, µs: PID {pi_us:.2f}, GrayPredictivePI {grey_us:.2f}")

    fmus = {path.stem: path for path in build_fmus(["Step", "FOPDT", "PID", "GrayPredictivePI"])}
    common = {"Kc": 2.0, "Ti": 20.0, "Ts": 0.1}
    own = {"PID": fmu_step_us(fmus["PID"], args.steps, args.repeat, {**common, "Td": 0.0}),
           "GrayPredictivePI": fmu_step_us(fmus["GrayPredictivePI"], args.steps, args.repeat, {**common, "B": 2.0})}
    loops = {}
    with tempfile.TemporaryDirectory() as tmp:
        for controller in ("PID", "GrayPredictivePI"):
            folder = Path(tmp) / controller
            folder.mkdir()
            (folder / "SystemStructure.ssd").write_text(LOOP.format(controller=controller, extra=EXTRA[controller]))
            loops[controller] = loop_step_us(folder, args.steps, args.repeat)
    print("FMU do_step alone (fmpy, set + doStep + get), µs per step:")
    for name, value in own.items():
        print(f"  {name:17s} {value:7.1f}")
    extra = own["GrayPredictivePI"] / own["PID"] - 1.0
    print(f"  grey PI FMU extra over the PI FMU: {100 * extra:.0f} % (target < 30 %)")
    print("Step -> controller -> FOPDT in the master, µs per master step:")
    for name, value in loops.items():
        print(f"  {name:17s} {value:7.1f}")
    added = (loops["GrayPredictivePI"] - loops["PID"]) / own["PID"]
    print(f"  loop time the grey PI adds, relative to the PI FMU's own step: {100 * added:.0f} %")


if __name__ == "__main__":
    main()
