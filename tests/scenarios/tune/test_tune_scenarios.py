"""``cosim tune`` on our FMUs: the command line end to end on ssp/pid_fopdt (best.ssv that
``cosim run --param-set`` takes, the table, the report), failed runs as penalised points (an
FMU refusing a parameter, an FMU killing its worker), and robust tuning over noise seeds on
ssp/pid_fopdt_noise."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pythonfmu.builder import FmuBuilder
from ssdgen import ssd_text, write_system

from cosim.present.metrics import step_metrics
from cosim.record.results import read
from cosim.tune import DifferentialEvolution, read_evaluations, tune

ROOT = Path(__file__).resolve().parents[3]
COSIM = str(Path(sys.executable).with_name("cosim"))
PID_FOPDT = ROOT / "ssp" / "pid_fopdt"


def _cosim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([COSIM, *args], capture_output=True, text=True)


def test_cosim_tune_writes_a_best_ssv_that_cosim_run_reproduces(built_fmus, tmp_path):
    out = tmp_path / "tuned"
    done = _cosim("tune", str(PID_FOPDT), "--param", "controller.Kc=2:40:log", "--param", "controller.Ti=5:80:log",
                  "--objective", "ITAE:plant.y", "--constraint", "overshoot:plant.y<=10%", "--stop", "80",
                  "--popsize", "5", "--max-evaluations", "20", "--workers", "2", "-o", str(out))
    assert done.returncode == 0, done.stderr
    rows = read_evaluations(out)
    assert len(rows) <= 20 and {r["status"] for r in rows} == {"completed"}
    best = min((r for r in rows if r["feasible"]), key=lambda r: r["objective"])
    assert f"cosim: best (evaluation {best['evaluation']}): controller.Kc = {best['controller.Kc']:.6g}" in done.stdout
    assert rows[0]["controller.Kc"] == 8.0345 and not rows[0]["feasible"]      # the scenario's PID: 33 % overshoot
    # the printed command reproduces the best point's objective and constraint
    command = next(line for line in done.stdout.splitlines() if line.startswith("cosim: run them: "))
    assert f"--param-set {out / 'best.ssv'} --stop 80.0" in command
    again = _cosim("run", str(PID_FOPDT), "--param-set", str(out / "best.ssv"), "--stop", "80",
                   "-o", str(tmp_path / "again.csv"), "--quiet")
    assert again.returncode == 0, again.stderr
    result = read(tmp_path / "again.csv")
    metrics = step_metrics(result["time"], result["plant.y"], result["setpoint.y"])
    assert metrics["ITAE"] == best["objective"] and metrics["overshoot"] == best["overshoot:plant.y <= 10"] <= 10
    page = (out / "tune.html").read_text()
    assert "<h2>Tuning</h2>" in page and "<h2>The best run</h2>" in page and "Metrics per event" in page
    summary = json.loads((out / "tune.json").read_text())["result"]
    assert summary["best"]["evaluation"] == best["evaluation"] and summary["failed"] == 0


def test_runs_an_fmu_refuses_are_penalised_points_with_their_error(built_fmus, tmp_path):
    # the PID refuses Ti <= 0 at initialisation: those points fail, the tuning goes on around them
    result = tune(PID_FOPDT, {"controller.Ti": (-20.0, 40.0)}, objective="ITAE:plant.y", stop_time=60,
                  method=DifferentialEvolution(popsize=8), max_evaluations=16, workers=2, output=tmp_path, report=False)
    failed = [ev for ev in result.evaluations if ev.values["controller.Ti"] <= 0]
    assert failed and all(ev.status == "failed" and ev.value == float("inf") for ev in failed)
    assert all(ev.error == "model_error" and "integral time Ti must be a finite number > 0" in ev.message
               for ev in failed), [ev.message for ev in failed]
    assert result.best.values["controller.Ti"] > 0 and result.best.status == "completed"
    rows = read_evaluations(tmp_path)
    assert {r["status"] for r in rows if r["controller.Ti"] <= 0} == {"failed"}


def final_time(result: np.ndarray) -> float:
    """The run's last time (a callable objective term)."""
    return float(result["time"][-1])


def test_a_run_that_kills_its_worker_is_a_failed_point_and_the_tuning_goes_on(tmp_path):
    fmu = Path(FmuBuilder.build_FMU(ROOT / "tests" / "scenarios" / "sweep" / "fmus" / "Aborting.py", dest=tmp_path,
                                    needsExecutionTool="false"))
    system = write_system(tmp_path / "system", {"Aborting.fmu": fmu},
                          ssd_text("crash", {"crash": ("Aborting.fmu", {"y": "output"})}, [], stop=1.0, step=0.05))
    result = tune(system, {"crash.abort_time": (0.2, 1.5)}, objective=final_time,
                  method=DifferentialEvolution(popsize=5, polish=0), max_evaluations=5, workers=2, output=tmp_path / "t",
                  report=False)
    lost = [ev for ev in result.evaluations if ev.values["crash.abort_time"] < 1.0]
    assert len(result.evaluations) == 5 and lost
    assert all(ev.status == "failed" and ev.error == "worker_lost" for ev in lost)
    assert all(ev.status == "completed" and ev.objective == 1.0 for ev in result.evaluations if ev not in lost)


def test_a_noisy_plant_is_tuned_on_the_mean_over_its_seeds_and_the_worst_seeds_constraint(built_fmus, tmp_path):
    noisy = ROOT / "ssp" / "pid_fopdt_noise"
    result = tune(noisy, {"controller.Td": (0.0, 3.0)}, objective="ITAE:plant.y:setpoint.y",
                  constraints=["overshoot:plant.y:setpoint.y<=40%"], seeds=[1, 2, 3], stop_time=60,
                  method=DifferentialEvolution(popsize=5, polish=0), max_evaluations=5, workers=2, output=tmp_path,
                  report=False)
    ev = result.best
    itae, overshoot = [], []
    for seed in (1, 2, 3):
        out = tmp_path / f"seed{seed}.csv"
        done = _cosim("run", str(noisy), "--param-set", str(result.ssv), "--start-value", f"noise.seed={seed}",
                      "--stop", "60", "-o", str(out), "--quiet")
        assert done.returncode == 0, done.stderr
        r = read(out)
        m = step_metrics(r["time"], r["plant.y"], r["setpoint.y"])
        itae.append(m["ITAE"])
        overshoot.append(m["overshoot"])
    assert len(set(itae)) == 3                                  # the seeds make different runs
    assert ev.objective == pytest.approx(float(np.mean(itae)), rel=1e-12)
    assert ev.constraints["overshoot:plant.y <= 40"] == max(overshoot)
    assert "--start-value noise.seed=1" in result.command
