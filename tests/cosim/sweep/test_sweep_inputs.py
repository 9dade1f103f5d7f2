"""`cosim sweep --input-file --start-value`: every run of the sweep is the `cosim run` of the
same scenario with the same input table and start values, sample for sample (bit for bit),
and the table's contents and the start values are part of the run id.

The scenario is a pair of C FMUs (``Drive``: y = gain * u, yk echoes the input k) whose inputs
come from the table by ``component.input`` (`cosim.plan.inputs`, fmpy's table rules).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from single_fmus import build_drive
from ssdgen import ssd_text, write_system

from cosim.cli import main
from cosim.record.results import read
from cosim.sweep import sweep

TABLE = "time,src.u,dst.k\n0,0,1\n0.5,1,1\n0.5,1,3\n1,2,3\n"


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("pair")
    drive = build_drive(folder / "fmu")
    return write_system(folder / "sys", {"Drive.fmu": drive}, ssd_text(
        "pair", {"src": ("Drive.fmu", {"u": "input", "y": "output"}),
                 "dst": ("Drive.fmu", {"u": "input", "k": "input", "x": "output", "y": "output"})},
        [("src", "y", "dst", "u")], stop=1.0, step=0.1))


def _run(tmp_path: Path, scenario: Path, table: Path, *starts: str) -> np.ndarray:
    out = tmp_path / f"run_{len(list(tmp_path.glob('run_*.csv')))}.csv"
    args = ["run", str(scenario), "--input-file", str(table), "-o", str(out), "-q"]
    for s in starts:
        args += ["--start-value", s]
    assert main(args) == 0
    return read(out)


def _assert_same(sweep_run: np.ndarray, single_run: np.ndarray) -> None:
    assert sweep_run.dtype.names == single_run.dtype.names
    for name in single_run.dtype.names:
        np.testing.assert_array_equal(sweep_run[name], single_run[name], err_msg=name)


def test_each_sweep_run_is_the_run_with_the_same_table_and_start_values(pair, tmp_path):
    table = tmp_path / "in.csv"
    table.write_text(TABLE)
    result = sweep(pair, {"dst.gain": ["2", "5"]}, start_values=["src.gain=3"], input_file=table,
                   output=tmp_path / "out", executor="serial")
    assert [r["status"] for r in result.rows] == ["completed"] * 2
    for row in result.rows:
        ours = read(tmp_path / "out" / "runs" / f"{row['run_id']}.csv")
        single = _run(tmp_path, pair, table, "src.gain=3", f"dst.gain={row['dst.gain']:g}")
        _assert_same(ours, single)
        assert list(ours["dst.k"]) == [1] * 5 + [3] * 6          # the table reached the run
        # the start value too (y is recorded one communication point after the u it is of, as fmpy records it)
        np.testing.assert_array_equal(ours["src.y"][1:], 3 * ours["src.u"][:-1])


def test_the_command_line_sweep_on_a_pool_and_the_run_id_follows_the_table(pair, tmp_path):
    table = tmp_path / "in.csv"
    table.write_text(TABLE)
    out = tmp_path / "out"
    args = ["sweep", str(pair), "--set", "dst.gain=4", "--input-file", str(table), "--start-value", "src.gain=3",
            "--workers", "1", "--output", str(out), "-q"]
    assert main(args) == 0
    first = sorted(p.name for p in (out / "runs").glob("*.csv"))
    assert len(first) == 1
    _assert_same(read(out / "runs" / first[0]), _run(tmp_path, pair, table, "src.gain=3", "dst.gain=4"))
    table.write_text(TABLE.replace("1,2,3", "1,2,7"))   # a changed table is a new run, not a skipped one
    assert main(args) == 0
    assert len(list((out / "runs").glob("*.csv"))) == 2
    assert main([*args[:-3], "--start-value", "src.gain=2", "--output", str(out), "-q"]) == 0
    assert len(list((out / "runs").glob("*.csv"))) == 3


def test_a_dask_cluster_gets_the_tables_contents_not_its_path(pair, tmp_path):
    """A cluster worker may not see the parent's files: the table goes to it as bytes
    (`cosim.sweep.shipping.execute_shipped`); the runs are the local runs bit for bit."""
    distributed = pytest.importorskip("distributed")
    table = tmp_path / "in.csv"
    table.write_text(TABLE)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        result = sweep(pair, {"dst.gain": ["2"]}, start_values=["src.gain=3"], input_file=table,
                       output=tmp_path / "out", executor=client)
    assert [r["status"] for r in result.rows] == ["completed"]
    ours = read(tmp_path / "out" / "runs" / f"{result.rows[0]['run_id']}.csv")
    _assert_same(ours, _run(tmp_path, pair, table, "src.gain=3", "dst.gain=2"))
