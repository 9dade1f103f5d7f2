"""benchmarks/bench_native.py end to end at a tiny size (2 FMUs, 200 steps of 1 ms): every peer
ran, and computed what cosim computed where its semantics say it must (no timing is asserted).

* cosim (each kernel this cosim has) and the C floor: the same exchange, equal to the last bit;
* independent systems (nothing connected): the container, libcosim and fmpy.ssp step the same
  FMUs on the same grid, so they agree to rounding (the container steps with its own h = 1 ms,
  cosim with t_{k+1} - t_k); fmpy.ssp has no initial row, its row k is cosim's row k + 1;
* chains (a feedthrough block behind the source): the container and libcosim are Jacobi, so they
  equal the C floor without settling, which lags cosim by a step; fmpy.ssp also starts its
  connectors at 0 (benchmarks/floor.py with ``initial_inputs="zero"``, one row shifted).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_native  # noqa: E402
from bench_native import KERNELS, PEERS, STEP, measure, table  # noqa: E402
from c_floor import compile_floor, run_c_floor  # noqa: E402
from floor import run_floor  # noqa: E402

STEPS = 200
STOP = STEPS * STEP
ROUNDING = 1e-9


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    return measure(["c", "om"], [2], STEPS, 1, fmpy_max=10, folder=tmp_path_factory.mktemp("bench_native"),
                   files_from=2)


def outputs(case) -> list[str]:
    return [f"{c}.{v}" for c, vs in case.outputs.items() for v in vs]


def close(a: np.ndarray, b: np.ndarray, what: str) -> None:
    np.testing.assert_allclose(a, b, rtol=0, atol=ROUNDING, err_msg=what)


@pytest.mark.slow   # 36 s on the shared 2-core machine (build/test-durations.json)
def test_every_peer_ran_every_case_and_the_table_has_a_row_each(cases):
    assert [(c.system.family.name, c.system.label) for c in cases] == [
        (bench_native.FAMILIES[f].name, label) for f in ("c", "om") for label in ("independent 2", "chained 2")]
    for case in cases:
        ran = {peer for peer in PEERS if peer != "cosim native" or "native" in KERNELS}
        assert set(case.results) == ran, case.why
        assert all(math.isfinite(case.best[p]) and case.best[p] > 0 for p in ran)
        assert math.isfinite(case.best["+csv"]) and math.isfinite(case.best["+parquet"])  # wall-time noise at this size
    lines = table(cases)
    assert len(lines) == 2 + len(cases) and all(line.count("|") == lines[0].count("|") for line in lines)


def test_cosim_and_the_c_floor_agree_to_the_last_bit(cases):
    for case in cases:
        mine = case.results["cosim python"]
        floor = case.results["C floor"]
        assert mine.dtype.names[1:] and set(mine.dtype.names) == set(floor.dtype.names)
        for name in mine.dtype.names:
            assert np.array_equal(mine[name], floor[name]), f"{case.system.label}: {name}"
        if "native" in KERNELS:
            for name in mine.dtype.names:
                assert np.array_equal(mine[name], case.results["cosim native"][name]), name


def jacobi(case, tmp_path: Path) -> np.ndarray:
    """The C floor without settling: what a Jacobi master computes."""
    return run_c_floor(compile_floor(tmp_path), case.fmus, case.outputs, case.system.connections, case.feedthrough,
                       0.0, STOP, STEP, settle=False)[1]


@pytest.mark.parametrize("topology", ["independent", "chained"])
def test_the_container_and_libcosim_compute_what_a_jacobi_master_computes(cases, topology, tmp_path):
    for case in (c for c in cases if c.system.topology == topology):
        expected = case.results["cosim python"] if topology == "independent" else jacobi(case, tmp_path)
        for name in outputs(case):
            close(case.results["container"][name], expected[name], f"container {name}")
            close(case.results["libcosim"][name], expected[name], f"libcosim {name}")
        if topology == "chained":  # the chain lags: Jacobi is not what cosim computes
            block = case.feedthrough[-1]
            assert not np.allclose(expected[f"{block}.y"], case.results["cosim python"][f"{block}.y"], atol=1e-6)


def test_fmpy_ssp_computes_what_its_documented_semantics_say(cases):
    for case in cases:
        signals = outputs(case)
        got = case.results["fmpy.ssp"]
        if case.system.topology == "independent":
            expected = case.results["cosim python"][1:]
        else:  # connectors start at 0, no initial row: benchmarks/floor.py with zero inputs, shifted
            expected = run_floor(case.fmus, [tuple(c) for c in case.system.connections], 0.0, STOP, STEP, signals,
                                 initial_inputs="zero")[2][1:]
        for name in signals:
            close(got[name], expected[name], f"fmpy.ssp {name}")
