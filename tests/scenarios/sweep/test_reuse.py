"""Issue 28: a sweep's workers keep the scenario and the FMU instances across runs (fmi2Reset /
fmi3Reset, then re-initialised with the run's values), and every run's results are the same,
sample for sample and byte for byte, as a fresh ``cosim run`` of it in a process of its own.

One scenario of each family in ssp/, each swept over values that change what the FMUs keep
between steps: the grey predictor's window (grey_fig312), a noise seed (grey_noise's
band-limited white noise, dpi_ch47's stochastic plant), GPC's on-line estimator (osmm_header),
the gain-scheduled PID's schedule (gs_sim2_1), the BTG plant's controllers, the SOPDT predictor,
the digital PI.  The sweep runs serially in this process, so every run after the first ran on
the instances the one before left, reset; its metadata says so (``reused_instances``).
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from cfmus import build_c_fmu, fmi2_description
from ssdgen import ssd_text, write_system

from cosim.sweep import sweep

ROOT = Path(__file__).resolve().parents[3]
COSIM = str(Path(sys.executable).with_name("cosim"))

#: scenario, swept values, seeds (and the seed parameter), stop time, start values
FAMILIES = {
    "pid_fopdt": ({"controller.Kc": [8.0345, 4.0]}, {}, 30.0, []),
    "grey_fig312": ({"predictor.n": [4, 6], "pi.Kc": [3.0]}, {}, 60.0, []),
    "grey_noise": ({}, {"seeds": [1, 2], "seed_parameters": ["noise.seed"]}, 30.0, []),
    "gs_sim2_1": ({"controller.A": [0.3499969475, 0.5]}, {}, 30.0, []),
    "btg_boiler_following": ({"fuel_pi.Kc": [8.246, 6.0]}, {}, 150.0, ["noise.power=0.01"]),
    "sopdt_nominal": ({"controller.K": [1.2, 1.5]}, {}, 400.0, []),
    "osmm_header": ({"controller.move_weight": [1.0, 2.0]}, {}, 150.0, ["setpoint.t_step=50", "setpoint.final=9.0"]),
    "dpi_ch47": ({"plant.seed": [1, 2]}, {}, 1.0, ["plant.Qeta_1_1=0.01", "plant.Qeta_2_2=0.01"]),
}


def _fresh_run(scenario: Path, ssv: Path, stop: float, start_values: list[str], out: Path) -> bytes:
    command = [COSIM, "run", str(scenario), "--param-set", str(ssv), "--stop", repr(stop), "-o", str(out), "--quiet"]
    for text in start_values:
        command += ["--start-value", text]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    return out.read_bytes()


@pytest.mark.parametrize("family", FAMILIES)
def test_reused_instances_give_what_fresh_runs_give(family, tmp_path):
    sets, seeding, stop, start_values = FAMILIES[family]
    scenario = ROOT / "ssp" / family
    result = sweep(scenario, sets, **seeding, stop_time=stop, start_values=start_values, output=tmp_path / "sweep",
                   executor="serial")
    assert [r["status"] for r in result.rows] == ["completed"] * len(result.rows), result.rows
    runs = tmp_path / "sweep" / "runs"
    for i, row in enumerate(result.rows):
        meta = json.loads((runs / f"{row['run_id']}.json").read_text())
        assert meta["reset_refused"] == {}
        # the first run instantiated every FMU; each later one ran on the instances reset
        assert len(meta["reused_instances"]) == (0 if i == 0 else len(meta["components"]))
        fresh = _fresh_run(scenario, runs / f"{row['run_id']}.ssv", stop, start_values, tmp_path / f"fresh{i}.csv")
        assert (runs / f"{row['run_id']}.csv").read_bytes() == fresh, f"run {i} of {family} differs from cosim run"
    first, *later = [(runs / f"{r['run_id']}.csv").read_bytes() for r in result.rows]
    assert all(other != first for other in later)       # the swept values changed the results


def test_fmi3_instances_are_reset_too(tmp_path):
    """pid_fopdt with our PID built for FMI 3.0 (fmus/fmi3/PID3.py, pythonfmu3): fmi3Reset, then
    the next run's values; each run as a fresh cosim run."""
    folder = tmp_path / "pid3"
    shutil.copytree(ROOT / "ssp" / "pid_fopdt", folder)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace("resources/PID.fmu", "resources/PID3.fmu"))
    result = sweep(folder, {"controller.Kc": [8.0345, 4.0, 6.0]}, stop_time=30.0, output=tmp_path / "sweep",
                   executor="serial")
    runs = tmp_path / "sweep" / "runs"
    metas = [json.loads((runs / f"{r['run_id']}.json").read_text()) for r in result.rows]
    assert "controller" in metas[1]["reused_instances"] and metas[1]["components"]["controller"]["interface"] == "fmi3-cs"
    for i, row in enumerate(result.rows):
        fresh = _fresh_run(folder, runs / f"{row['run_id']}.ssv", 30.0, [], tmp_path / f"fresh{i}.csv")
        assert (runs / f"{row['run_id']}.csv").read_bytes() == fresh, f"run {i} differs from cosim run"


def test_a_pool_sweep_in_any_order_equals_a_fresh_sweep_and_writes_the_table_only_when_asked(tmp_path):
    values = {"controller.Kc": [2.0, 5.0, 8.0, 3.0, 6.5, 4.0]}
    scenario = ROOT / "ssp" / "pid_fopdt"
    fresh = sweep(scenario, values, stop_time=20.0, metrics=["plant.y:setpoint.y"], output=tmp_path / "fresh",
                  executor="process", workers=2, reuse=False)
    reused = sweep(scenario, values, stop_time=20.0, metrics=["plant.y:setpoint.y"], output=tmp_path / "reused",
                   executor="process", workers=2)
    table_only = sweep(scenario, values, stop_time=20.0, metrics=["plant.y:setpoint.y"], output=tmp_path / "table",
                       executor="process", workers=2, run_files=False)
    def strip(rows) -> str:   # NaN (an undefined metric) compares equal as text
        return json.dumps([{k: v for k, v in r.items() if k != "wall_time"} for r in rows])
    assert strip(reused.rows) == strip(fresh.rows) == strip(table_only.rows)
    for row in fresh.rows:
        name = f"{row['run_id']}.csv"
        assert (tmp_path / "reused" / "runs" / name).read_bytes() == (tmp_path / "fresh" / "runs" / name).read_bytes()
        assert "reused_instances" not in json.loads((tmp_path / "fresh" / "runs" / f"{row['run_id']}.json").read_text())
    reused_meta = [json.loads((tmp_path / "reused" / "runs" / f"{r['run_id']}.json").read_text()) for r in reused.rows]
    assert sum(bool(m["reused_instances"]) for m in reused_meta) >= len(values["controller.Kc"]) - 2   # 2 workers
    assert not (tmp_path / "table" / "runs").exists()
    assert {p.name for p in (tmp_path / "table").iterdir()} - {"sweep.parquet"} == {"sweep.csv", "sweep.png"}


def test_a_dask_worker_keeps_the_shipped_scenario_and_its_instances(tmp_path):
    """On a LocalCluster the scenario is shipped: the shared files are named by content, so the
    worker's second and third runs reuse its instances; the results are the pool's."""
    pytest.importorskip("distributed")
    values = {"controller.Kc": [2.0, 5.0, 8.0]}
    scenario = ROOT / "ssp" / "pid_fopdt"
    local = sweep(scenario, values, stop_time=20.0, output=tmp_path / "local", executor="serial", reuse=False)
    dask = sweep(scenario, values, stop_time=20.0, output=tmp_path / "dask", executor="local:1")
    metas = [json.loads((tmp_path / "dask" / "runs" / f"{r['run_id']}.json").read_text()) for r in dask.rows]
    assert sorted(len(m["reused_instances"]) for m in metas) == [0, 4, 4]
    for row in local.rows:
        name = f"{row['run_id']}.csv"
        assert (tmp_path / "dask" / "runs" / name).read_bytes() == (tmp_path / "local" / "runs" / name).read_bytes()


INTEGRATOR = fmi2_description("Integrator", [("k", 0, "parameter", 1.0), ("y", 1, "output", None)], {"y": []},
                              "{5d1c6f1e-28aa-4d3b-9c61-000000000028}")
INTEGRATOR_BODY = r"""
static void start(S *s) { s->r[0] = 1.0; s->r[1] = 0.0; }
static void calculate(S *s) { }
static int step(S *s, double t, double h) { s->r[1] += s->r[0] * h; return 0; }
"""


def test_an_fmu_whose_reset_fails_is_instantiated_afresh_for_every_run(tmp_path):
    """The C FMU's fmi2Reset returns Error (tests/cfmus.py): the pool frees it, says why, and every
    later run instantiates it again; results as fresh."""
    fmu = build_c_fmu(tmp_path / "c", "Integrator", INTEGRATOR, INTEGRATOR_BODY)
    folder = write_system(tmp_path / "system", {"Integrator.fmu": fmu},
                          ssd_text("integrate", {"i": ("Integrator.fmu", {"y": "output"})}, [], stop=1.0, step=0.1))
    result = sweep(folder, {"i.k": [1.0, 2.0, 3.0]}, output=tmp_path / "out", executor="serial")
    runs = tmp_path / "out" / "runs"
    metas = [json.loads((runs / f"{r['run_id']}.json").read_text()) for r in result.rows]
    assert [m["reused_instances"] for m in metas] == [[], [], []]
    assert all("fmi2Reset failed" in m["reset_refused"]["Integrator.fmu"] for m in metas)
    for k, row in zip((1.0, 2.0, 3.0), result.rows):
        last = (runs / f"{row['run_id']}.csv").read_text().splitlines()[-1].split(",")
        assert float(last[1]) == pytest.approx(k * 1.0)
