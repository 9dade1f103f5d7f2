"""Every scenario of ssp/ against its stored reference (tests/references/<scenario>.csv), through the
`cosim_regression` fixture of our own pytest plugin (cosim.pytest_plugin), as a user's suite would use it.

Runs are shortened to the first few hundred steps around the scenario's first setpoint or load change, so
the whole file runs in well under a minute (table `RUNS`).  Rewrite the references after an intended change:

    python -m pytest tests/scenarios/test_regression.py --cosim-update-references

Tolerances.  The runs are deterministic: fixed-step master, plants integrated with fixed steps (exact ZOH,
RK4 sub-steps), noise sources seeded in the SSD; on one machine two runs agree bit for bit.  The references
are checked on other machines too (CI), where libm, BLAS and the scipy solvers inside the FMUs (QP in GPC,
least squares in the grey and fuzzy models) may round differently in the last bit, and closed loops carry that
along; such differences stay around 1e-12 relative over a few hundred steps.  So every signal must match to
rtol = 1e-9 (plus atol = 1e-9 in the signal's own unit, for samples at or near zero): far below anything
a modelling change produces, far above rounding.  Discrete decisions (saturation, mode switching, OSMM's
group choice) could in principle flip on such a rounding difference; none is close to its threshold in
these windows, and a flip would show as a failure, not be hidden.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from cosim.read import ssp
from peers import gemseo_fmu_dir

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = sorted(p.name for p in (ROOT / "ssp").iterdir() if (p / "SystemStructure.ssd").is_file())
PARAMS = Path(__file__).resolve().parents[1] / "references" / "params"

RTOL, ATOL = 1e-9, 1e-9


@dataclass(frozen=True)
class Run:
    """A shortened regression run: stop time [s], the compared signals (controlled variables,
    control signals, the setpoint), parameter sets (paths from the repository root), decimation, and
    whether the scenario needs gemseo-fmu's FMUs (`peers.gemseo_fmu_dir`)."""
    stop: float
    signals: tuple[str, ...]
    param_sets: tuple[str, ...] = ()
    decimate: int | None = None
    gemseo_fmus: bool = False


PID_LOOP = ("setpoint.y", "plant.y", "controller.u")
GS_LOOP = PID_LOOP + ("controller.Kc",)
DPI = ("plant.y1", "plant.y2", "controller.u1", "controller.u2")
PREDICTOR = ("process.y", "predictor.x_hat", "predictor.a", "predictor.b")

# stop times: the first setpoint or input change plus its first transient, a few hundred steps.
RUNS: dict[str, Run] = {
    # Sim. 4.1 at 58 MW with the PI (the default parameters hold the unit at equilibrium): the +1 kgf/cm²
    # pressure set-point step at 100 s, 600 steps of 0.5 s.
    "btg_boiler_following": Run(300.0, ("pressure_sp.y", "plant.P", "plant.E", "plant.L", "fuel_cmd.y",
                                        "turbine.u", "level.u"),
                                ("ssp/btg_boiler_following/sim41_58.ssv", "ssp/btg_boiler_following/pi.ssv")),
    "dpi_ch47": Run(4.0, DPI),                        # the whole run: 400 steps of 0.01 s
    "dpi_wood_berry": Run(400.0, DPI),                # the whole run: 400 steps of 1 s
    "dpi_wood_berry_decentral": Run(400.0, ("plant.y1", "plant.y2", "pi1.u", "pi2.u")),
    "grey_gm3t1": Run(210.0, ("u.y", "process.y", "identifier.ks", "identifier.wn", "identifier.zeta",
                              "identifier.valid")),   # step at 10 s, 420 samples of 0.5 s
    # the input step moved from 320 s to 40 s (tests/references/params/grey_noise.ssv); 800 steps of 0.1 s,
    # every 4th sample stored (200 rows) since the three predictors sample at 1 s and 5 s.
    "grey_noise": Run(80.0, ("u.y", "process.y", "measurement.y", "grey_1s.x_hat", "grey_5s.x_hat",
                             "ldispi.x_hat"), (str(PARAMS / "grey_noise.ssv"),), decimate=4),
    "grey_fig312": Run(60.0, ("setpoint.y", "pi_plant.y", "out_plant.y", "predictor.x_hat", "out_pi.u",
                              "grey_plant.y")),   # setpoint step at 20 s, 600 steps of 0.1 s
    "grey_pi_vs_pi": Run(60.0, ("setpoint.y", "pi_plant.y", "pi.u", "grey_plant.y", "grey_pi.u",
                                "grey_pi.mode")),     # setpoint step at 20 s, 600 steps of 0.1 s
    "grey_sim33": Run(300.0, PREDICTOR),              # the rise from 250 s, 300 steps of 1 s
    "grey_sim34": Run(400.0, PREDICTOR),              # the rise from 320 s, 400 steps of 1 s
    # ch. 5 conclusion 1: the load step d = 6 at 50 s and its first 50 s, 1000 steps of 0.1 s
    "gs_ch5_large_disturbance": Run(100.0, GS_LOOP + ("load.y",)),
    "gs_sim2_1": Run(60.0, GS_LOOP),                  # setpoint step at 10 s, 600 steps of 0.1 s
    "gs_sim2_2": Run(60.0, GS_LOOP),
    "gs_sim2_3": Run(60.0, GS_LOOP),
    "gs_sim2_4": Run(60.0, GS_LOOP),
    "gs_sim2_5": Run(60.0, GS_LOOP),
    # valve 1's step moved from 2050 s to 50 s (tests/references/params/osmm_header.ssv): 300 steps of 1 s
    # (the GPC is the slowest FMU here, ~10 ms a step).
    "osmm_header": Run(300.0, ("header.y1", "header.y2", "header.fuel", "controller.u1", "controller.u2",
                               "controller.u3", "controller.active_group"), (str(PARAMS / "osmm_header.ssv"),)),
    "osmm_mfrls": Run(300.0, ("u1.y", "u2.y", "plant.h1", "plant.h2", "mfrls.y_hat1", "mfrls.y_hat2",
                              "global_frls.y_hat1", "local_frls.y_hat1")),   # PRBS from 100 s, 300 steps of 1 s
    "pid_fopdt": Run(60.0, PID_LOOP),                 # setpoint step at 10 s, 600 steps of 0.1 s
    # pid_fopdt with seeded measurement noise (noise.seed 1 in the SSD): the step at 10 s, 600 steps of 0.1 s
    "pid_fopdt_noise": Run(60.0, ("setpoint.y", "plant.y", "measurement.y", "controller.u")),
    # Mass_Damper.fmu (OpenModelica, from gemseo-fmu): setpoint step at 0.5 s; 3000 steps of 0.2 ms (the
    # scenario's step, its CS export's stability limit), every 10th sample stored (300 rows).
    "pid_mass_damper": Run(0.6, ("setpoint.y", "plant.y", "controller.u"), decimate=10,
                           gemseo_fmus=True),
    # the same loop with the plant integrated by the master through its Model Exchange interface: the whole run,
    # 300 steps of 0.01 s (setpoint step at 1.5 s)
    "pid_mass_damper_me": Run(3.0, ("setpoint.y", "plant.y", "controller.u"), gemseo_fmus=True),
    "sopdt_nmp": Run(600.0, PID_LOOP),                # setpoint step at 40 s, 300 steps of 2 s
    "sopdt_nominal": Run(600.0, PID_LOOP),
    "sopdt_pid_itae": Run(600.0, PID_LOOP),
    # the 5 % fuel step at 30 s, its first 30 s: values converted between kgf/cm2, MPa, mm, m, fraction, %
    "units_demo": Run(60.0, ("boiler.fuel_disturbance", "boiler.P", "pressure.y", "boiler.L", "level.y")),
}


def test_every_scenario_has_a_regression_run_and_a_default_experiment():
    """A new scenario folder must get an entry in RUNS; each SSD states its stop time and step size."""
    assert sorted(RUNS) == SCENARIOS
    for name in SCENARIOS:
        structure = ssp.load(ROOT / "ssp" / name)
        try:
            assert structure.stop_time is not None and structure.step_size is not None, name
            assert RUNS[name].stop <= structure.stop_time, name
        finally:
            structure.close()


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_matches_reference(name, cosim_regression):
    run = RUNS[name]
    fmu_dirs = [gemseo_fmu_dir()] if run.gemseo_fmus else []
    result = cosim_regression(ROOT / "ssp" / name, reference=f"{name}.csv", stop=run.stop,
                              param_sets=[ROOT / p for p in run.param_sets], fmu_dirs=fmu_dirs,
                              signals=list(run.signals), rtol=RTOL, atol=ATOL, decimate=run.decimate)
    assert result["time"][-1] == pytest.approx(run.stop)
