"""``cosim new`` (issue 45, `cosim.scaffold`): a scenario that closes a loop of one of our controllers
around a third-party plant (gemseo-fmu's OpenModelica Mass_Damper.fmu) runs as written, ports
matched by causality with the plant's units on the connectors, and says what is left to wire;
``cosim info X.fmu`` lists any FMU's parameters; an SSD naming an FMU nobody has gets "did you
mean".  About 10 s."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from cosim.read.ssp import load
from cosim.record.results import read
from peers import gemseo_fmu_dir
from runhelpers import cli_exit, refused


@pytest.fixture(scope="module")
def mass_damper() -> Path:
    return gemseo_fmu_dir() / "Mass_Damper.fmu"


def test_new_scenario_around_a_third_party_plant_runs(capsys, tmp_path, mass_damper, built_fmus):
    folder = tmp_path / "my_loop"
    cli_exit(capsys, 0, "new", str(folder), "--plant", str(mass_damper), "--setpoint", "-0.45")
    structure = load(folder)
    connections = {(c.start_element, c.start_connector, c.end_element, c.end_connector)
                   for c in structure.connections}
    assert connections == {("setpoint", "y", "controller", "r"), ("plant", "y", "controller", "y"),
                           ("controller", "u", "plant", "f")}
    plant = structure.components["plant"]
    assert plant.implementation == "ModelExchange" and plant.connectors["f"].unit == "N"
    assert "Ts" in (folder / "controller.ssv").read_text()
    assert "- nothing: every input the controller reads is connected." in (folder / "README.md").read_text()
    result = tmp_path / "r.csv"
    assert main(["run", str(folder), "-o", str(result), "--quiet"]) == 0, capsys.readouterr().err
    assert "cosim: warning" not in capsys.readouterr().err
    meta = json.loads(result.with_suffix(".json").read_text())
    assert meta["units"]["plant.f"] == "N" and meta["units"]["controller.u"] == "N"
    samples = read(result)
    assert np.all(np.isfinite(samples["plant.y"])) and samples["setpoint.y"][-1] == -0.45


def test_new_says_what_is_left_to_wire(capsys, tmp_path, mass_damper, built_fmus):
    main(["new", str(tmp_path / "gs"), "--plant", str(mass_damper), "--controller", "GainScheduledPID"])
    out = capsys.readouterr().out
    assert "left to wire: controller.W: the controller's scheduling input (needed when law in 0 1 2 3)" in out
    assert "controller.Kp: the controller's process input (needed when law in 4)" in out
    err = refused(capsys, "new", str(tmp_path / "gs"), "--plant", str(mass_damper))
    assert "already holds a SystemStructure.ssd" in err
    err = refused(capsys, "new", str(tmp_path / "x"), "--plant", str(mass_damper), "--controller", "GainSchedPID")
    assert "no controller FMU 'GainSchedPID'" in err
    err = refused(capsys, "new", str(tmp_path / "x"), "--plant", str(mass_damper), "--controller", "GreyPredictor")
    assert "GreyPredictor.fmu is not a controller" in err


def test_info_lists_any_fmus_parameters_with_units_defaults_and_ranges(capsys, mass_damper):
    assert main(["info", str(mass_damper)]) == 0
    out = capsys.readouterr().out
    assert "parameters (7):" in out
    line = next(line for line in out.splitlines() if line.strip().startswith("spring.c"))
    assert "N/m" in line and "10000.0" in line and ">= 0.0" in line and "Spring constant" in line


def test_info_of_our_fmu_says_what_to_wire(capsys, built_fmus):
    assert main(["info", str(built_fmus["GainScheduledPID"])]) == 0
    out = capsys.readouterr().out
    assert "sampled every Ts (default 0.1 s)" in out and "W (scheduling, when law in 0 1 2 3)" in out
    assert "drives the plant: u" in out


def test_an_fmu_file_nobody_has_gets_did_you_mean(capsys, tmp_path, built_fmus):
    text = re.sub(r'\s*<ssd:ParameterBindings>\s*<ssd:ParameterBinding source="controller.ssv"/>\s*'
                  r'</ssd:ParameterBindings>', "", Path("ssp/pid_fopdt/SystemStructure.ssd").read_text())
    ssd = tmp_path / "SystemStructure.ssd"
    ssd.write_text(text.replace("resources/PID.fmu", "resources/GreyPredictivPI.fmu"))
    err = refused(capsys, "validate", str(ssd))
    assert "Did you mean 'GreyPredictivePI.fmu'" in err
    ssd.write_text(text.replace("resources/PID.fmu", "resources/GreyPredictivePI.fmu"))
    assert main(["validate", str(ssd)]) == 0, capsys.readouterr().err   # the alias is GrayPredictivePI.fmu


def test_help_and_counts_read_as_text(capsys, built_fmus, tmp_path):
    """Issue 45 item 8: no reStructuredText markup in --help, '1 FMU' not '1 FMUs'."""
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "``" not in capsys.readouterr().out
    assert main(["run", str(built_fmus["Step"]), "-o", str(tmp_path / "s.csv")]) == 0
    out = capsys.readouterr().out
    assert "1 FMU, 0 connections" in out and "FMUs" not in out
