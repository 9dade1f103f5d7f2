"""`cosim sweep`: combinations × seeds on a process pool and a Dask cluster, the results table,
reruns that skip finished runs, failed runs as rows, names refused before any run.

The scenario is a small real SSP system of our FMUs: a step setpoint, a PID on an FOPDT plant,
band-limited white noise (which has a ``seed`` parameter) added to the measurement.
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from ssdgen import ssd_text, write_system

from cosim.cli import main
from cosim.errors import SetupError
from cosim.present.metrics import METRICS, step_metrics
from cosim.record.results import read
from cosim.sweep import parse_seeds, parse_set, read_table, sweep

SETS = {"controller.Kc": ["4", "8"], "plant.T": ["15", "20"]}
SEEDS = [1, 2]
METRIC = "plant.y:setpoint.y"


def _loop(folder: Path, fmus: dict[str, Path], noise: bool = True) -> Path:
    comps = {"setpoint": ("Step.fmu", {"y": "output"}),
             "controller": ("PID.fmu", {"r": "input", "y": "input", "u": "output"}),
             "plant": ("FOPDT.fmu", {"u": "input", "y": "output"}),
             "sensor": ("Sum.fmu", {"u1": "input", "u2": "input", "y": "output"})}
    conns = [("setpoint", "y", "controller", "r"), ("sensor", "y", "controller", "y"),
             ("controller", "u", "plant", "u"), ("plant", "y", "sensor", "u1")]
    params = {"setpoint": {"t_step": 1.0}}
    if noise:
        comps["noise"] = ("BandLimitedWhiteNoise.fmu", {"y": "output"})
        conns.append(("noise", "y", "sensor", "u2"))
        params["noise"] = {"power": 0.001, "Ts": 0.5}
    names = ["Step", "PID", "FOPDT", "Sum"] + (["BandLimitedWhiteNoise"] if noise else [])
    return write_system(folder, {f"{n}.fmu": fmus[n] for n in names},
                        ssd_text("loop", comps, conns, stop=20.0, step=0.1, parameters=params))


def _nan_as_none(row: dict) -> dict:
    """NaN metrics (a response that never settles) compare equal to each other."""
    return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in row.items()}


@pytest.fixture(scope="module")
def scenario(built_fmus, tmp_path_factory) -> Path:
    return _loop(tmp_path_factory.mktemp("sweep") / "loop", built_fmus)


@pytest.fixture(scope="module")
def pool_sweep(scenario, tmp_path_factory):
    """The 2 × 2 parameters × 2 seeds sweep on a 2-process pool."""
    out = tmp_path_factory.mktemp("pool")
    return sweep(scenario, SETS, seeds=SEEDS, metrics=[METRIC], output=out, executor="process", workers=2), out


def test_pool_runs_every_combination_and_records_it(pool_sweep):
    result, out = pool_sweep
    assert result.ran == 8 and result.skipped == 0 and len(result.rows) == 8
    assert {(r["controller.Kc"], r["plant.T"], r["seed"]) for r in result.rows} == \
        {(kc, t, s) for kc in (4.0, 8.0) for t in (15.0, 20.0) for s in SEEDS}
    assert len({r["run_id"] for r in result.rows}) == 8
    for row in result.rows:
        assert row["status"] == "completed" and row["message"] is None and row["wall_time"] > 0
        meta = json.loads((out / "runs" / f"{row['run_id']}.json").read_text())
        assert meta["status"] == "completed"
        assert meta["parameters"]["controller.Kc"] == row["controller.Kc"]
        assert meta["parameters"]["plant.T"] == row["plant.T"]
        assert meta["parameters"]["noise.seed"] == row["seed"]


def test_the_summary_figure_has_a_panel_per_metric_and_swept_parameter(pool_sweep, tmp_path, scenario):
    import matplotlib.image

    result, out = pool_sweep
    assert result.figure == out / "sweep.png"
    height, width, _ = matplotlib.image.imread(result.figure).shape
    assert (height, width) == (round(2.3 * len(METRICS) * 110), round((3.6 * len(SETS) + 0.8) * 110))
    plain = sweep(scenario, {"plant.T": ["15"]}, output=tmp_path, executor="serial", stop_time=2.0)
    assert plain.figure is None and not (tmp_path / "sweep.png").exists()      # no metrics, no figure


def test_metrics_are_those_of_the_run_csv(pool_sweep):
    result, out = pool_sweep
    for row in result.rows:
        data = read(out / "runs" / f"{row['run_id']}.csv")
        expected = step_metrics(data["time"], data["plant.y"], data["setpoint.y"])
        for key in METRICS:
            got = row[f"plant.y:{key}"]
            assert (math.isnan(got) and math.isnan(expected[key])) or got == pytest.approx(expected[key], abs=1e-12)
    assert len({row["plant.y:IAE"] for row in result.rows}) == 8


def test_seeds_drive_the_noise(pool_sweep):
    result, out = pool_sweep
    noise = {(r["controller.Kc"], r["plant.T"], r["seed"]): read(out / "runs" / f"{r['run_id']}.csv")["noise.y"]
             for r in result.rows}
    # the noise source does not depend on the loop: same seed, same noise; another seed, other noise
    np.testing.assert_array_equal(noise[(4.0, 15.0, 1)], noise[(8.0, 20.0, 1)])
    np.testing.assert_array_equal(noise[(4.0, 15.0, 2)], noise[(8.0, 15.0, 2)])
    assert not np.allclose(noise[(4.0, 15.0, 1)], noise[(4.0, 15.0, 2)])
    assert np.std(noise[(4.0, 15.0, 1)]) > 0


def test_csv_and_parquet_tables_agree(pool_sweep):
    result, out = pool_sweep
    parquet = pq.read_table(out / "sweep.parquet")
    assert parquet.schema.field("controller.Kc").type == "double"
    assert parquet.schema.field("seed").type == "int64"
    csv = pacsv.read_csv(out / "sweep.csv", convert_options=pacsv.ConvertOptions(
        column_types=parquet.schema, null_values=[""], strings_can_be_null=True))   # "nan" is NaN, not null
    assert csv.column_names == parquet.column_names == result.columns
    for a, b, c in zip(csv.to_pylist(), parquet.to_pylist(), result.rows):
        assert a.keys() == b.keys() == c.keys()
        for key in a:
            same = [x for x in (a[key], b[key], c[key])]
            if isinstance(same[0], float) and math.isnan(same[0]):
                assert all(math.isnan(x) for x in same), key
            else:
                assert same[0] == same[1] == same[2], key


def test_rerun_skips_finished_runs_and_runs_only_new_values(pool_sweep, scenario):
    result, out = pool_sweep
    again = sweep(scenario, SETS, seeds=SEEDS, metrics=[METRIC], output=out, executor="serial")
    assert (again.ran, again.skipped) == (0, 8)
    assert [_nan_as_none(r) for r in again.rows] == [_nan_as_none(r) for r in result.rows]
    more = sweep(scenario, {**SETS, "plant.T": ["15", "20", "25"]}, seeds=SEEDS, metrics=[METRIC], output=out,
                 executor="serial")
    assert (more.ran, more.skipped, len(more.rows)) == (4, 8, 12)
    assert {r["plant.T"] for r in more.rows if r["run_id"] not in {x["run_id"] for x in result.rows}} == {25.0}
    assert len(read_table(out / "sweep.parquet")) == 12


def test_force_reruns_the_runs_already_done(scenario, tmp_path, capsys):
    """Issue 42 item 4: ``cosim sweep --force`` reruns every run (the CLI passed it on to no executor)."""
    argv = ["sweep", str(scenario), "--set", "plant.T=15,20", "--output", str(tmp_path), "--workers", "1"]
    for extra, summary in (([], "2 ran now, 0 already done"), ([], "0 ran now, 2 already done"),
                           (["--force"], "2 ran now, 0 already done")):
        assert main(argv + extra) == 0
        assert summary in capsys.readouterr().out, extra


def test_same_table_on_a_dask_local_cluster(pool_sweep, scenario, tmp_path):
    distributed = pytest.importorskip("distributed")
    result, _ = pool_sweep
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        dask = sweep(scenario, SETS, seeds=SEEDS, metrics=[METRIC], output=tmp_path, executor=client)
    assert dask.ran == 8
    assert [r["run_id"] for r in dask.rows] == [r["run_id"] for r in result.rows]
    for a, b in zip(dask.rows, result.rows):
        assert a["status"] == b["status"] == "completed"
        for key in [c for c in result.columns if c.startswith("plant.y:")]:
            assert (math.isnan(a[key]) and math.isnan(b[key])) or abs(a[key] - b[key]) <= 1e-12, key


def test_a_refused_value_is_a_failed_row_and_the_others_complete(scenario, tmp_path, capsys, monkeypatch):
    # T = 0 passes the model description (no min) but the FOPDT FMU refuses it at initialisation;
    # the runs go to a Dask LocalCluster the CLI starts (--scheduler local:N), whose workers
    # unpack the scenario into $TMPDIR/cosim-sweep/ (a folder of this test's own here)
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    monkeypatch.setattr(tempfile, "tempdir", None)
    (tmp_path / "tmp").mkdir()
    status = main(["sweep", str(scenario), "--set", "plant.T=20,0", "--metrics", METRIC,
                   "--scheduler", "local:2", "--output", str(tmp_path), "--quiet"])
    assert status == 1
    rows = read_table(tmp_path / "sweep.parquet")
    by_t = {r["plant.T"]: r for r in rows}
    assert by_t[20.0]["status"] == "completed" and not math.isnan(by_t[20.0]["plant.y:IAE"])
    assert by_t[0.0]["status"] == "failed" and by_t[0.0]["error"] == "model_error"
    assert by_t[20.0]["error"] is None
    assert "time constant T must be a finite number > 0" in by_t[0.0]["message"]
    assert by_t[0.0]["plant.y:IAE"] is None
    assert "failed" in capsys.readouterr().err
    assert not (tmp_path / "tmp" / "cosim-sweep").exists()  # the workers' copies removed at the end


@pytest.mark.parametrize("args, expected", [
    (["--set", "controller.Kcc=1,2"], "Did you mean 'Kc'"),
    (["--set", "controler.Kc=1,2"], "Did you mean 'controller'"),
    (["--set", "controller.Kc=fast"], "'fast' is not a Real value"),
    (["--set", "controller.Kc"], "is not NAME=VALUE"),
    (["--set", "plant.tau=-1"], "below the variable's minimum 0.0"),
    (["--seeds", "3..1"], "is not a list of seeds"),
    (["--set", "plant.T=1,2", "--metrics", "plant.yy:setpoint.y"], "Did you mean 'plant.y'"),
    (["--seeds", "1,2", "--seed-parameter", "noise.sed"], "Did you mean 'seed'"),
    (["--set", "plant.T=1,2", "--scheduler", "local:two"], "give local:N"),
    (["--set", "plant.T=1,2", "--scheduler", "tcp://sched"], "'tcp://sched' is not a Dask scheduler address"),
    (["--seeds", "1,2", "--set", "noise.seed=3"], "both swept with --set and set by --seeds"),
    # issue 17: every value checked before the first run
    (["--set", "plant.tau=4,nan"], "'nan' is not a finite number"),
    (["--set", "plant.T=1:inf:3"], "is not a Real value"),
    (["--seeds", f"1,{2**32 + 1}"], "4294967297 is outside the range of an FMI 2.0 Integer [-2147483648, 2147483647]"),
    (["--set", f"controller.integral_mode=1,{2**31}"], "outside the range of an FMI 2.0 Integer"),
    (["--seeds", "1..1000000000"], "the sweep has 1,000,000,000 runs (1000000000 seeds)"),
    (["--set", "plant.T=1:2:2000", "--set", "controller.Kc=1:2:1000"], "the sweep has 2,000,000 runs"),
])
def test_bad_arguments_are_refused_before_any_run(scenario, tmp_path, capsys, args, expected):
    assert main(["sweep", str(scenario), *args, "--output", str(tmp_path / "out"), "--quiet"]) == 2
    assert expected in capsys.readouterr().err
    assert not (tmp_path / "out" / "runs").exists() or not any((tmp_path / "out" / "runs").glob("*.csv"))


def test_seeds_need_a_seed_parameter(built_fmus, tmp_path):
    quiet = _loop(tmp_path / "quiet", built_fmus, noise=False)
    with pytest.raises(SetupError, match="no component of the scenario has a parameter named 'seed'"):
        sweep(quiet, {}, seeds=[1, 2], output=tmp_path / "out", executor="serial")


def test_argument_forms():
    assert parse_set("plant.T=1, 2,3") == ("plant.T", ["1", "2", "3"])
    assert list(parse_seeds("1..4")) == [1, 2, 3, 4] and parse_seeds("1,5,9") == [1, 5, 9]


def test_range_values_are_evenly_spaced_and_typed_by_the_variable(scenario, tmp_path):
    result = sweep(scenario, {"plant.T": ["10:20:3"], "controller.integral_mode": ["1:3:3"]}, output=tmp_path,
                   executor="serial", stop_time=2.0)
    assert [(r["plant.T"], r["controller.integral_mode"]) for r in result.rows] == \
        [(t, mode) for t in (10.0, 15.0, 20.0) for mode in (1, 2, 3)]
    assert all(r["status"] == "completed" for r in result.rows)
    schema = pq.read_schema(tmp_path / "sweep.parquet")
    assert (schema.field("plant.T").type, schema.field("controller.integral_mode").type) == ("double", "int64")
    with pytest.raises(SetupError, match="does not fall on integers"):
        sweep(scenario, {"controller.integral_mode": ["1:2:3"]}, output=tmp_path, executor="serial")


def test_sweep_of_an_ssp_archive(scenario, tmp_path):
    archive = tmp_path / "loop.ssp"
    assert main(["pack", str(scenario), "-o", str(archive)]) == 0
    first = sweep(archive, {"plant.T": ["10", "20"]}, output=tmp_path / "out", executor="serial", stop_time=2.0)
    assert [r["status"] for r in first.rows] == ["completed", "completed"]
    again = sweep(archive, {"plant.T": ["10", "20"]}, output=tmp_path / "out", executor="serial", stop_time=2.0)
    assert (again.ran, again.skipped) == (0, 2)


def test_the_fmus_are_checked_against_the_parents_limit_before_any_run(scenario, tmp_path):
    """--max-unpacked applies to the FMUs when the sweep's plan is validated (issue 17: validate
    applies every archive check run's extraction does), so no worker starts."""
    from cosim.safeio import unpack_limit

    with unpack_limit(1000), pytest.raises(SetupError, match="--max-unpacked") as refused:
        sweep(scenario, {"plant.T": ["10"]}, output=tmp_path, executor="process", workers=1, stop_time=2.0)
    assert "1000 bytes" in str(refused.value) and not (tmp_path / "sweep.csv").exists()


def test_a_one_parameter_sweep_figure_is_a_grid_with_units_and_no_band_without_repeats(scenario, tmp_path):
    """Issue 27: six metrics of one swept parameter were six panels in a narrow column, their y
    labels without units, and a 'min-max band' drawn through single runs."""
    import matplotlib.image

    from cosim.present.metrics import metric_unit
    from cosim.sweep.figure import metric_label

    result = sweep(scenario, {"plant.T": ["15", "20"]}, metrics=[METRIC], output=tmp_path, executor="serial",
                   stop_time=5.0)
    height, width, _ = matplotlib.image.imread(result.figure).shape
    assert (height, width) == (round(2 * 2.3 * 110), round((3 * 3.6 + 0.8) * 110))    # 2 rows × 3 columns
    assert metric_label("plant.y:overshoot", {}) == "overshoot of plant.y [%]"
    assert metric_label("plant.y:IAE", {"plant.y": "m"}) == "IAE of plant.y [m·s]"
    assert (metric_unit("ISE", "m"), metric_unit("ITAE", "K"), metric_unit("peak_error", "N"),
            metric_unit("IAE", None)) == ("m²·s", "K·s²", "N", "s")


def test_the_figure_draws_a_band_only_where_a_value_has_repeats():
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from cosim.sweep.figure import draw

    single = [{"status": "completed", "k": k, "p.y:IAE": 1.0 + k} for k in (1, 2)]
    bands = {}
    for name, rows in (("single", single), ("repeated", single + [{"status": "completed", "k": 1, "p.y:IAE": 3.0}])):
        fig = draw(rows, ["k"], ["p.y:IAE"], name, {"p.y": "m"})
        bands[name] = sum(isinstance(c, PolyCollection) for c in fig.axes[0].collections)
        assert fig.axes[0].get_ylabel() == "IAE of p.y [m·s]"
        assert fig._suptitle.get_text().endswith("(one run per value)" if name == "single"
                                                 else "(median, min-max band, every run)")
        plt.close(fig)
    assert bands == {"single": 0, "repeated": 1}
