"""The master on our own FMUs (built by `greyfmu build` through the FMU provider) and the scenarios."""
from __future__ import annotations

import json

import numpy as np
import pytest

import cosim
from cosim.cli import main
from cosim.record.results import read
from ssdgen import ssd_text, write_system

SCENARIO = "ssp/pid_fopdt"


@pytest.fixture(scope="module")
def pid_fopdt():
    return cosim.simulate(SCENARIO)


def at(result, name, t):
    return result[name][np.argmin(np.abs(result["time"] - t))]


def test_pid_fopdt_reaches_setpoint_and_rejects_the_load(pid_fopdt):
    """Steady state of 20 dx/dt + x = 0.2 (u + d): y = r needs u = r/0.2 - d: 5 before the load
    step, 6 after it (d = -1)."""
    r = pid_fopdt
    assert r["time"][-1] == 300 and len(r) == 3001
    assert at(r, "plant.y", 140) == pytest.approx(1.0, abs=5e-3)
    assert at(r, "controller.u", 140) == pytest.approx(5.0, abs=5e-2)
    assert at(r, "plant.y", 300) == pytest.approx(1.0, abs=1e-4)
    assert at(r, "controller.u", 300) == pytest.approx(6.0, abs=1e-3)
    assert r["plant.y"][r["time"] <= 14.0 + 1e-9].max() == 0.0      # dead time 4 s after the step at 10 s
    assert r["plant.y"][r["time"] > 14.2].max() > 1.1                 # the load-ITAE tuning overshoots
    assert at(r, "plant.y", 160) < 0.99                                # the load pulls y down


def test_inputs_see_outputs_before_the_first_step(tmp_path):
    """Initialisation propagates outputs to inputs: with y0 = 0.5 the controller's measurement
    input is 0.5 at t = 0, not 0.0."""
    text = open(f"{SCENARIO}/SystemStructure.ssd").read().replace(
        '<ssv:Parameter name="y0"><ssv:Real value="0"/>', '<ssv:Parameter name="y0"><ssv:Real value="0.5"/>')
    folder = tmp_path / "s"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(text)
    (folder / "controller.ssv").write_text(open(f"{SCENARIO}/controller.ssv").read())
    r = cosim.simulate(folder, stop_time=1)
    assert r["controller.y"][0] == 0.5 and r["plant.y"][0] == 0.5


def test_plant_result_does_not_depend_on_the_master_step(tmp_path, built_fmus):
    comps = {"src": ("Step.fmu", {"y": "output"}), "plant": ("FOPDT.fmu", {"u": "input", "y": "output"})}
    folder = write_system(tmp_path / "s", {"Step.fmu": built_fmus["Step"], "FOPDT.fmu": built_fmus["FOPDT"]},
                          ssd_text("open", comps, [("src", "y", "plant", "u")], stop=42.0,
                                   parameters={"src": {"t_step": 0.0, "initial": 0.0, "final": 1.0}}))
    fine = cosim.simulate(folder, step_size=0.1, use_providers=False)
    coarse = cosim.simulate(folder, step_size=0.7, use_providers=False)
    t = coarse["time"]
    exact = np.where(t > 4, 0.2 * (1 - np.exp(-(t - 4) / 20)), 0.0)
    np.testing.assert_allclose(coarse["plant.y"], exact, atol=1e-12)
    np.testing.assert_allclose(np.interp(t, fine["time"], fine["plant.y"]), coarse["plant.y"], atol=1e-12)


def test_last_step_is_clamped_to_the_stop_time(tmp_path):
    r = cosim.simulate(SCENARIO, stop_time=1.05)
    assert list(r["time"][-3:]) == pytest.approx([0.9, 1.0, 1.05])


def test_linear_transformation_and_feedthrough_chain(tmp_path, built_fmus):
    """Step -> Gain (k = 3) -> Sum (k1 = 1, k2 = -1) with a LinearTransformation on the way:
    both blocks have direct feedthrough, and the chain settles within each instant."""
    comps = {"src": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"}),
             "sum": ("Sum.fmu", {"u1": "input", "u2": "input", "y": "output"})}
    fmus = {f"{n}.fmu": built_fmus[n] for n in ("Step", "Gain", "Sum")}
    folder = write_system(tmp_path / "s", fmus, ssd_text(
        "chain", comps, [("src", "y", "gain", "u", 2.0, 1.0), ("gain", "y", "sum", "u1"), ("src", "y", "sum", "u2")],
        stop=2.0, step=0.25, parameters={"src": {"t_step": 1.0, "initial": 1.0, "final": 2.0},
                                         "gain": {"k": 3.0}, "sum": {"k2": -1.0}}))
    r = cosim.simulate(folder, use_providers=False)
    np.testing.assert_allclose(r["gain.u"], 2 * r["src.y"] + 1, atol=1e-12)
    np.testing.assert_allclose(r["sum.y"], 3 * (2 * r["src.y"] + 1) - r["src.y"], atol=1e-12)
    assert r["sum.y"][0] == 8.0 and r["sum.y"][-1] == 13.0


def test_gauss_seidel_differs_from_jacobi_by_one_step_of_delay(pid_fopdt):
    gs = cosim.simulate(SCENARIO, algorithm="gauss-seidel")
    diff = np.max(np.abs(gs["plant.y"] - pid_fopdt["plant.y"]))
    assert 0 < diff < 0.05


def test_param_set_on_the_command_line_wins(tmp_path, pid_fopdt):
    csv = tmp_path / "pi.csv"
    assert main(["run", SCENARIO, "-q", "-o", str(csv), "--param-set", f"{SCENARIO}/pi_only.ssv"]) == 0
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["parameters"]["controller.Td"] == 0.0 and meta["parameters"]["controller.Kc"] == 8.0345
    pi = read(csv)
    assert np.max(np.abs(pi["plant.y"] - pid_fopdt["plant.y"])) > 0.01


def test_pack_then_run_the_archive_gives_the_same_result(tmp_path, pid_fopdt):
    ssp = tmp_path / "pid_fopdt.ssp"
    assert main(["pack", SCENARIO, "-o", str(ssp)]) == 0
    import zipfile
    names = set(zipfile.ZipFile(ssp).namelist())
    assert {"SystemStructure.ssd", "controller.ssv", "pi_only.ssv", "resources/PID.fmu", "resources/FOPDT.fmu",
            "resources/Step.fmu"} == names
    packed = cosim.simulate(ssp, use_providers=False)
    for name in pid_fopdt.dtype.names:
        np.testing.assert_array_equal(packed[name], pid_fopdt[name])


def test_run_writes_csv_plot_and_metadata(tmp_path, capsys):
    csv, png = tmp_path / "r.csv", tmp_path / "r.png"
    assert main(["run", SCENARIO, "--stop", "50", "-o", str(csv), "--plot", str(png),
                 "--signals", "setpoint.y,plant.y", "controller.*"]) == 0
    out = capsys.readouterr().out
    assert str(csv) in out and str(png) in out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    r = read(csv)
    assert r.dtype.names == ("time", "setpoint.y", "load.y", "controller.r", "controller.y", "controller.u",
                             "controller.e", "plant.u", "plant.d", "plant.y")
    meta = json.loads(csv.with_suffix(".json").read_text())
    assert meta["status"] == "completed" and meta["algorithm"] == "jacobi" and meta["step_size"] == 0.1


def test_signal_glob_that_matches_nothing(capsys):
    assert main(["run", SCENARIO, "-q", "--stop", "1", "--plot", "x.png", "--signals", "plant.z"]) == 2
    assert "no signal matches 'plant.z'" in capsys.readouterr().err


def test_info_lists_components_connections_and_parameters(capsys):
    assert main(["info", SCENARIO]) == 0
    out = capsys.readouterr().out
    assert "controller: PID.fmu (FMI 2.0, PythonFMU" in out
    assert "controller.u -> plant.u" in out and "controller.Kc = 8.0345" in out and "controller.ssv" in out


def _stderr_on_a_terminal(argv: list[str]) -> str:
    """What `cosim` writes to stderr when stderr is a terminal (a pseudo-terminal, read as it comes)."""
    import os
    import subprocess
    import sys
    import threading

    master, slave = os.openpty()
    chunks: list[bytes] = []

    def drain() -> None:
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:       # the other end closed
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=drain)
    reader.start()
    try:
        done = subprocess.run([sys.executable, "-m", "cosim.cli", *argv], stderr=slave, stdout=subprocess.DEVNULL,
                              timeout=300)
    finally:
        os.close(slave)
        reader.join(timeout=10)
        os.close(master)
    assert done.returncode == 0
    return b"".join(chunks).decode(errors="replace")


def test_progress_bar_on_runs_longer_than_a_second(tmp_path):
    """120 000 steps take well over a second (the bar waits a second: 60 000 steps took 0.9-1.5 s once
    the FMUs' step cost fell, issue 42, and the bar came and went with the machine's load): the bar
    appears on a terminal's stderr (and not with --quiet; nor in a log file, tests/cosim/test_cli_truth.py)."""
    args = ["run", SCENARIO, "--step", "0.0025", "-o", str(tmp_path / "r.csv")]
    assert "step/s" in _stderr_on_a_terminal(args)
    assert "step/s" not in _stderr_on_a_terminal(args + ["--quiet"])
