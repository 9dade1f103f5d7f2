"""The tests of tests/cosim/test_kernel.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosim.errors import SetupError
from cosim.kernel import library
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from runhelpers import assert_same, run_kernel as _run
from peers import gemseo_fmu_dir


ROOT = Path(__file__).parents[2]
pytestmark = pytest.mark.skipif(library()[0] is None, reason=f"no compiled kernel: {library()[1]}")






ALL_SCENARIOS = sorted(p.parent.name for p in (ROOT / "ssp").glob("*/SystemStructure.ssd"))


#: one scenario of each family in the default suite (a pythonfmu run costs ~1 s of instantiation);
#: COSIM_KERNEL_SCENARIOS=all runs every one (all passed when the kernel was written)
FAMILIES = {"btg_boiler_following", "dpi_wood_berry", "grey_sim33", "gs_sim2_1", "osmm_mfrls", "pid_fopdt",
            "pid_mass_damper", "pid_mass_damper_me", "sopdt_nmp", "units_demo"}


SCENARIOS = ALL_SCENARIOS if os.environ.get("COSIM_KERNEL_SCENARIOS") == "all" else \
    [s for s in ALL_SCENARIOS if s in FAMILIES]


def test_the_default_scenarios_exist():
    assert FAMILIES <= set(ALL_SCENARIOS)


@pytest.mark.parametrize("scenario, parameter_sets", [(s, ()) for s in SCENARIOS]
                         + [("pid_fopdt", ("pi_only.ssv",)), ("grey_sim33", ("ph40.ssv",))])
def test_scenarios_run_the_same_in_both_loops(scenario, parameter_sets):
    """A scenario of ssp/ (pythonfmu FMUs, and OpenModelica's from gemseo-fmu) for 100 steps,
    both loops, sample by sample."""
    folder, fmu_dirs = ROOT / "ssp" / scenario, [gemseo_fmu_dir()]
    sets = [folder / p for p in parameter_sets]
    step = prepare(folder, fmu_dirs=fmu_dirs)
    try:
        stop = step.grid.start + 100 * step.grid.step
    finally:
        step.close()
    results = {}
    for kernel in ("python", "auto"):
        prepared = prepare(folder, stop_time=stop, fmu_dirs=fmu_dirs, parameter_sets=sets)
        try:
            results[kernel] = run(prepared, kernel=kernel)
        finally:
            prepared.close()
    assert_same(results["python"][0], results["auto"][0])
    meta = results["auto"][1]
    kinds = {c["interface"] for c in meta["components"].values()}
    assert meta["kernel"] == "native", meta.get("kernel_reason")
    in_python = " ".join(meta.get("python_operations", {}))
    assert ("Model Exchange" in in_python) == bool(kinds - {"fmi2-cs", "fmi3-cs"})
    assert ("algebraic loop" in in_python) == ((meta["algebraic_loops"] or {}).get("mode") == "iterate")


def test_threads_keep_pythonfmu_components_serial_and_refuse_gauss_seidel(tmp_path):
    folder = ROOT / "ssp" / "pid_fopdt"
    python, threaded = _run(folder, "python", tmp_path), None
    prepared = prepare(folder, stop_time=1.0)
    try:
        threaded = run(prepared, threads=2)
        with pytest.raises(SetupError, match=r"--threads 2 steps components in parallel within a Jacobi step"):
            run(prepare(folder, stop_time=1.0, algorithm="gauss-seidel"), threads=2)
    finally:
        prepared.close()
    assert threaded[1]["parallel_components"] == []
    assert all("pythonfmu FMU" in why for why in threaded[1]["serial_components"].values())
    assert_same(threaded[0], python[0][:len(threaded[0])])
