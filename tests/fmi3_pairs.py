"""An FMU of ours and its FMI 3.0 sibling (greyfmu.fmi3) run alone in the same master, `cosim`,
over the FMI 2.0 FMU's DefaultExperiment with a representative input: every input steps at a
fifth of the run from its start value s to s + 0.05 k max(1, |s|) (k = 1, 2, ... in name order,
so that no two inputs move alike: a PID's r and y give an error) and ramps back to s by the end
(an input table, cosim.inputs), so each input's path through the model is exercised."""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree
import zipfile

import numpy as np


def experiment_and_inputs(fmu: Path) -> tuple[float, float, float, dict[str, float]]:
    """The FMI 2.0 FMU's DefaultExperiment (start, stop, step) and its inputs' start values."""
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    experiment = root.find("DefaultExperiment")
    start, stop, step = (float(experiment.get(key)) for key in ("startTime", "stopTime", "stepSize"))
    inputs = {variable.get("name"): float(variable[0].get("start", "0"))
              for variable in root.iter("ScalarVariable") if variable.get("causality") == "input"}
    return start, stop, step, inputs


def input_table(path: Path, start: float, stop: float, inputs: dict[str, float]) -> Path | None:
    """The representative input of the module docstring as a CSV table; None for an FMU without inputs."""
    if not inputs:
        return None
    names = sorted(inputs)
    step_time = start + 0.2 * (stop - start)
    rows = [[start, *(inputs[name] for name in names)], [step_time, *(inputs[name] for name in names)]]
    rows += [[step_time, *(inputs[name] + 0.05 * k * max(1.0, abs(inputs[name])) for k, name in enumerate(names, 1))]]
    rows += [[stop, *(inputs[name] for name in names)]]
    path.write_text("time," + ",".join(names) + "\n" + "".join(",".join(repr(v) for v in row) + "\n" for row in rows))
    return path


def max_difference(fmi2: Path, fmi3: Path, folder: Path) -> tuple[float, int, int]:
    """Max |FMI 2.0 - FMI 3.0| over every output sample of the two runs, the number of samples and
    of outputs compared; the two runs must have the same times."""
    import cosim

    start, stop, step, inputs = experiment_and_inputs(fmi2)
    table = input_table(folder / f"{fmi2.stem}_in.csv", start, stop, inputs)
    options = {"input_file": table} if table is not None else {}
    two = cosim.simulate_fmu(fmi2, **options)
    three = cosim.simulate_fmu(fmi3, **options)
    assert np.array_equal(two["time"], three["time"]), f"{fmi2.stem}: the two runs' times differ"
    outputs = [name for name in two.dtype.names if name != "time" and name.split(".", 1)[-1] not in inputs]
    by_name = {name.split(".", 1)[-1]: name for name in three.dtype.names}
    worst = 0.0
    for name in outputs:
        other = by_name[name.split(".", 1)[-1]]
        both_finite = np.isfinite(two[name]) & np.isfinite(three[other])
        assert np.array_equal(np.isfinite(two[name]), np.isfinite(three[other])), f"{name}: NaN in one run only"
        worst = max(worst, float(np.max(np.abs(two[name][both_finite] - three[other][both_finite]), initial=0.0)))
    return worst, len(two), len(outputs)
