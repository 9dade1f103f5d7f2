"""The FMI-LS-REF reference experiment each FMU of ours carries (build side; not embedded in the FMUs).

FMI Layered Standard References (FMI-LS-REF), tag v1.0.0-beta.1 of github:modelica/fmi-ls-ref
(2026-07-01): related files live in ``extra/org.fmi-standard.fmi-ls-ref/``, described by
``fmi-ls-manifest.xml`` (root ``fmiReferences``, ``<Related type source role description>``).
An experiment file is in the MA-HS-Experiments format (github:modelica/ma-hs-experiments, its
schema maHarmonizedSpecificationExperiments.xsd, MIME type ``application/x-ma-hs-experiments``,
suffix ``.exp``): ``<Experiments name><Experiment name><TransientSimulation startTime stopTime
stepSize/><Stimuli source/><References source/></Experiment></Experiments>``, CSV time series.
The standard's text still gives ``fmi-ls-version`` as 1.0.0-alpha.1 at that tag; we write the
tag's version.  Neither document says how close a run must come to the references: our
tolerances ride in the experiment's ``<Annotations>`` (FMI 3.0's annotation element) as
``<Annotation type="org.greyfmu.comparison">`` with one ``<Tolerance signal rtol atol time/>``
per output; ``cosim verify`` reads them (another tool ignores them, as FMI annotations allow).

What each FMU carries (`reference_entries`, called by `greyfmu.build` on the finished archive):

- ``reference.exp``: one experiment, ``default``: the FMU's DefaultExperiment (start, stop,
  step) with a representative input (`stimuli`);
- ``default_in.csv`` (an FMU with inputs): the stimuli, fmpy's input-table format;
- ``default_ref.csv``: every output at every communication point, as FMPy's ``simulate_fmu``
  computes it from the FMU just built (in a child process, so nothing the FMU imports stays in
  the building one); numbers written with ``repr``, so a rebuild writes the same bytes;
- the manifest, and ``documentation/fmi-ls-ref.txt`` (the standard's recommended note).

The representative input (no paper prescribes one for an FMU alone): each input steps once,
from its start value s by 0.1·|s| (by 1 where s = 0), input k of n at the communication point
t0 + h·round(N·(0.1 + 0.8·k/n)) (N steps of h in the experiment), computed as FMPy and cosim
compute their grid, t0 + k·h: both apply the value after the step from that point on (FMPy's
rule for an event on a communication point; between points FMPy would add one), so the
reference's grid is the DefaultExperiment's.  Tolerances: rtol 1e-6, atol 1e-6 of the output's largest
magnitude (at least 1e-9), time one communication step.

None of these files is hashed into the GUID (`greyfmu.dropin.stable_guid` hashes the model
description and ``resources/``): they follow from it.
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

from greyfmu.dropin import BuildError

FOLDER = "extra/org.fmi-standard.fmi-ls-ref/"
LS_VERSION = "1.0.0-beta.1"
LS_NAMESPACE = "http://fmi-standard.org/fmi-ls-manifest"
LS_DESCRIPTION = "Layered Standard providing information on related files included in an FMU."
EXPERIMENTS_TYPE = "application/x-ma-hs-experiments"
ANNOTATION = "org.greyfmu.comparison"
RTOL = 1e-6
ATOL_SHARE = 1e-6
ATOL_FLOOR = 1e-9


def _number(x: float) -> str:
    return repr(float(x))


def _csv(names: list[str], rows: list[list[float]]) -> bytes:
    head = ",".join(f'"{n}"' for n in names)
    return ("\n".join([head] + [",".join(map(_number, row)) for row in rows]) + "\n").encode()


def stimuli(start: float, stop: float, step: float, starts: dict[str, float]) -> list[list[float]]:
    """Rows (time, inputs...) of the representative input (module docstring); an event is a
    repeated time."""
    values = dict(starts)
    rows = [[start, *values.values()]]
    n, steps = len(values), round((stop - start) / step)
    for k, name in enumerate(values):
        at = start + round(steps * (0.1 + 0.8 * k / n)) * step      # a communication point, as hosts compute them
        rows.append([at, *values.values()])
        s = starts[name]
        values[name] = s + (0.1 * abs(s) if s != 0 else 1.0)
        rows.append([at, *values.values()])
    rows.append([stop, *values.values()])
    return rows


def _described(fmu: Path) -> tuple[ElementTree.Element, dict[str, float], list[str]]:
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    fmi3 = root.get("fmiVersion", "").startswith("3")
    variables = list(root.find("ModelVariables")) if fmi3 else root.findall("ModelVariables/ScalarVariable")
    starts, outputs = {}, []
    for v in variables:
        start = v.get("start") if fmi3 else v[0].get("start")
        if v.get("causality") == "input":
            starts[v.get("name")] = float(start or 0.0)
        elif v.get("causality") == "output":
            outputs.append(v.get("name"))
    return root, starts, outputs


RUNNER = """
import sys, numpy as np
from fmpy import simulate_fmu
fmu, stimuli, out, start, stop, step, *outputs = sys.argv[1:]
table = None
if stimuli != "-":
    data = np.genfromtxt(stimuli, delimiter=",", names=True, deletechars="")
    table = np.array(data, dtype=[(n, float) for n in data.dtype.names])
r = simulate_fmu(fmu, start_time=float(start), stop_time=float(stop), step_size=float(step),
                 output_interval=float(step), input=table, output=outputs, validate=False)
np.save(out, np.column_stack([r[n] for n in ("time", *outputs)]))
"""


def run_reference(fmu: Path, rows: list[list[float]], names: list[str], start: float, stop: float, step: float,
                  outputs: list[str]) -> list[list[float]]:
    """Every output at every communication point of the FMU with the input ``rows``, run by
    FMPy in a child Python (so the FMU's modules stay out of this process)."""
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="greyfmu-lsref-") as temp:
        table = Path(temp) / "in.csv"
        if rows:
            table.write_bytes(_csv(names, rows))
        out = Path(temp) / "out.npy"
        done = subprocess.run([sys.executable, "-c", RUNNER, str(fmu), str(table) if table.exists() else "-", str(out),
                               _number(start), _number(stop), _number(step), *outputs],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise BuildError(f"{fmu.name}: its reference experiment failed in FMPy: {done.stderr.strip()[-2000:]}")
        return np.load(out).tolist()


def _manifest(model: str, inputs: bool) -> bytes:
    related = [(EXPERIMENTS_TYPE, "reference.exp", "experiment/validation",
                f"{model}: its DefaultExperiment with a representative input, the result to expect and the "
                "tolerances (annotation org.greyfmu.comparison)"),
               ("text/csv", "default_ref.csv", "result", f"{model}: every output of the experiment 'default'")]
    if inputs:
        related.append(("text/csv", "default_in.csv", "testcase", f"{model}: the inputs of the experiment 'default'"))
    body = "".join(f"\n  <Related type={quoteattr(t)} source={quoteattr(s)} role={quoteattr(r)} "
                   f"description={quoteattr(d)}/>" for t, s, r, d in related)
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiReferences xmlns:fmi-ls="{LS_NAMESPACE}" '
            f'fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref" fmi-ls:fmi-ls-version="{LS_VERSION}" '
            f'fmi-ls:fmi-ls-description={quoteattr(LS_DESCRIPTION)}>{body}\n</fmiReferences>\n').encode()


def _experiments(model: str, start: float, stop: float, step: float, inputs: bool,
                 tolerances: dict[str, tuple[float, float, float]]) -> bytes:
    stimuli_line = '\n    <Stimuli source="default_in.csv"/>' if inputs else ""
    rows = "".join(f"\n          <Tolerance signal={quoteattr(name)} rtol=\"{_number(r)}\" atol=\"{_number(a)}\" "
                   f"time=\"{_number(t)}\"/>" for name, (r, a, t) in tolerances.items())
    about = quoteattr(f"The reference experiment of {model}, made when the FMU was built: run it and compare "
                      f"with cosim verify {model}.fmu")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<Experiments name={quoteattr(f"{model} reference")} description={about}>
  <Experiment name="default" description="DefaultExperiment, each input stepping once">
    <TransientSimulation startTime="{_number(start)}" stopTime="{_number(stop)}" stepSize="{_number(step)}"/>{stimuli_line}
    <References source="default_ref.csv"/>
    <Annotations>
      <Annotation type="{ANNOTATION}">
        <Comparison mode="tube">{rows}
        </Comparison>
      </Annotation>
    </Annotations>
  </Experiment>
</Experiments>
""".encode()


def _note(model: str, names: list[str], rows: list[list[float]]) -> bytes:
    steps = "".join(f"\n  {name} steps at t = {rows[1 + 2 * k][0]!r} s from {rows[1 + 2 * k][1 + k]!r} to "
                    f"{rows[2 + 2 * k][1 + k]!r}" for k, name in enumerate(names[1:]))
    return (f"{model}: reference experiment (FMI-LS-REF {LS_VERSION}, extra/org.fmi-standard.fmi-ls-ref/)\n\n"
            "reference.exp runs the DefaultExperiment" + (f" with these inputs (default_in.csv):{steps}" if steps else
                                                          " (the FMU has no inputs)") +
            "\nand default_ref.csv holds every output at every communication point, as FMPy computed it when the FMU "
            "was built.\nA run in another tool should stay within the tolerances of the annotation "
            f"{ANNOTATION}: rtol {RTOL:g}, atol {ATOL_SHARE:g} of each output's largest magnitude, time one "
            "communication step.\nCheck it with: cosim verify " + f"{model}.fmu\n").encode()


def reference_entries(fmu: Path) -> dict[str, bytes]:
    """The archive entries of the reference experiment of the built ``fmu`` (module docstring)."""
    import numpy as np

    root, starts, outputs = _described(fmu)
    model = root.get("modelName")
    experiment = root.find("DefaultExperiment")
    start = float(experiment.get("startTime", "0"))
    stop, step = float(experiment.get("stopTime")), float(experiment.get("stepSize"))
    names = ["time", *starts]
    rows = stimuli(start, stop, step, starts) if starts else []
    result = run_reference(fmu, rows, names, start, stop, step, outputs)
    peaks = np.max(np.abs(np.array(result)[:, 1:]), axis=0) if result else np.zeros(len(outputs))
    tolerances = {name: (RTOL, max(ATOL_SHARE * float(peak), ATOL_FLOOR), step) for name, peak in zip(outputs, peaks)}
    entries = {FOLDER + "fmi-ls-manifest.xml": _manifest(model, bool(starts)),
               FOLDER + "reference.exp": _experiments(model, start, stop, step, bool(starts), tolerances),
               FOLDER + "default_ref.csv": _csv(["time", *outputs], result),
               "documentation/fmi-ls-ref.txt": _note(model, names, rows)}
    if starts:
        entries[FOLDER + "default_in.csv"] = _csv(names, rows)
    return entries


def with_reference(fmu: Path, write_archive) -> None:
    """Rewrite the archive ``fmu`` with its reference experiment added (``write_archive(path,
    entries)``: the build's own archive writer, so entry order and time stamps stay the build's)."""
    with zipfile.ZipFile(fmu) as archive:
        entries = {info.filename: archive.read(info) for info in archive.infolist()}
    entries.update(reference_entries(fmu))
    write_archive(fmu, entries)
