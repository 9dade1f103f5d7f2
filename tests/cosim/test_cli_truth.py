"""One CLI truth (issue 27, item 3): the synopsis of docs/master.md (once the README's) and each
subcommand's --help name the same options, the help says what the code does, and the command
line's own values, --quiet, the progress bar, --version and shell completion behave as documented."""
from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from cosim.cli import _parser, main
from ssdgen import ssd_text, write_system

ROOT = Path(__file__).resolve().parents[2]
OPTION = r"(?<![\w-])(--?[a-z][a-z0-9-]*)"
COMPONENTS = {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"})}


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    return next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction)).choices


def _synopsis() -> dict[str, set[str]]:
    """The options of each `cosim SUB` of the synopsis block of docs/master.md (# The master), comments left out."""
    block = (ROOT / "docs" / "master.md").read_text().split("# The master", 1)[1].split("```", 2)[1]
    options: dict[str, set[str]] = {}
    current = None
    for line in block.splitlines():
        start = re.match(r"cosim (\w+)", line)
        current = start.group(1) if start else (current if line.startswith(" ") else None)
        if current:
            options.setdefault(current, set()).update(re.findall(OPTION, line.split("#")[0]))
    return options


@pytest.mark.parametrize("name", sorted(_subcommands()))
def test_master_synopsis_and_help_name_the_same_options(name):
    """Every option docs/master.md gives a subcommand exists, and every option of its --help is in it
    (an option with an alias, e.g. --stop/--stop-time, by any of its names)."""
    documented = _synopsis().get(name, set())
    actions = [a for a in _subcommands()[name]._actions
               if a.option_strings and a.help != argparse.SUPPRESS and "--help" not in a.option_strings]
    known = {o for a in actions for o in a.option_strings}
    assert documented <= known, f"cosim {name}: docs/master.md names options it lacks: {sorted(documented - known)}"
    missing = [a.option_strings for a in actions if not documented & set(a.option_strings)]
    assert not missing, f"cosim {name}: options of --help docs/master.md does not document: {missing}"


def test_help_says_what_the_code_does(capsys):
    """--threads is implemented (cosim.run.execution, the compiled kernel's pool); cosim runs more than
    FMI 2.0 Co-Simulation."""
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    run_help = " ".join(capsys.readouterr().out.split())
    assert "not implemented" not in run_help and "--threads N threads making the doSteps" in run_help
    with pytest.raises(SystemExit):
        main(["--help"])
    top = " ".join(capsys.readouterr().out.split())
    assert "single FMUs (FMI 2.0, 3.0; CS, ME)" in top and "FMI 2.0 Co-Simulation FMUs" not in top


def test_version_is_the_package_metadata(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.strip() == f"cosim (greyfmu) {version('greyfmu')}"


@pytest.mark.parametrize("shell, marker", [("bash", "-F _shtab_cosim cosim"), ("zsh", "#compdef cosim")])
def test_completion_script_knows_subcommands_and_options(shell, marker, capsys):
    assert main(["completion", shell]) == 0
    script = capsys.readouterr().out
    assert marker in script and "--loop-tolerance" in script and "sweep" in script and "--param-set" in script


def _pair(tmp_path, twin_fmus, **kw) -> Path:
    text = ssd_text("pair", COMPONENTS, [("step", "y", "gain", "u")], parameters={"gain": {"k": 4.0}}, **kw)
    return write_system(tmp_path / "pair", {"Step.fmu": twin_fmus["Step"], "Gain.fmu": twin_fmus["Gain"]}, text)


@pytest.mark.parametrize("argv, message", [
    (["--stop", "-5"], "cosim: error: --stop -5: the stop time -5.0 is not after the start time 0.0."),
    (["--start", "3", "--stop", "2"], "cosim: error: --stop 2: the stop time 2.0 is not after the start time 3.0."),
    (["--step", "1e-300", "--start", "1e300", "--stop", "2e300"], "cosim: error: --step 1e-300: the step size"),
])
def test_a_command_line_time_is_blamed_on_its_option_not_on_the_ssd(tmp_path, twin_fmus, capsys, argv, message):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    assert main(["run", str(folder), "-o", str(tmp_path / "o.csv"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and "SystemStructure.ssd" not in err, err


def test_a_non_finite_command_line_time_is_refused_with_the_text_given(tmp_path, twin_fmus, capsys):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    with pytest.raises(SystemExit) as done:
        main(["run", str(folder), "--stop", "1e400"])
    assert done.value.code == 2
    assert "argument --stop/--stop-time: 1e400 is not a finite number of seconds" in capsys.readouterr().err


def test_an_ssd_time_is_still_blamed_on_the_ssd(tmp_path, twin_fmus, capsys):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('stopTime="2.0"', 'stopTime="-1"'))
    assert main(["run", str(folder), "-o", str(tmp_path / "o.csv")]) == 2
    assert "SystemStructure.ssd, ssd:DefaultExperiment stopTime: the stop time -1.0" in capsys.readouterr().err


@pytest.mark.parametrize("value, message", [
    ("nope.k=1,2", "cosim: error: --set nope.k: system-level parameter 'nope.k' does not start with a component"),
    ("gain.nope=1,2", "cosim: error: --set gain.nope: the FMU Gain.fmu has no variable 'nope'."),
])
def test_sweep_set_errors_name_the_option_once(tmp_path, twin_fmus, capsys, value, message):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    assert main(["sweep", str(folder), "--set", value, "-o", str(tmp_path / "sw")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and "--set, --set" not in err and "cosim sweep --set" not in err, err


def test_metrics_suggestions_name_the_option_given(tmp_path, twin_fmus, capsys):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    out = tmp_path / "o.csv"
    assert main(["run", str(folder), "-o", str(out)]) == 0
    for option in ("--signal", "--setpoint"):
        argv = {"--signal": "gain.y", "--setpoint": "step.y", option: "gain.yy"}
        assert main(["metrics", str(out), *(x for kv in argv.items() for x in kv)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"cosim: error: {option}: no signal matches 'gain.yy'. Did you mean 'gain.y'"), err


def test_validate_takes_parameter_sets(tmp_path, twin_fmus, capsys):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    ssv = tmp_path / "bad.ssv"
    ssv.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet version="1.0" name="bad" '
                   'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
                   '<ssv:Parameters><ssv:Parameter name="gain.nope"><ssv:Real value="1"/></ssv:Parameter>'
                   '</ssv:Parameters></ssv:ParameterSet>\n')
    assert main(["validate", str(folder), "--param-set", str(ssv)]) == 2
    assert "bad.ssv" in (err := capsys.readouterr().err) and "nope" in err, err
    good = tmp_path / "good.ssv"
    good.write_text(ssv.read_text().replace("gain.nope", "gain.k"))
    assert main(["validate", str(folder), "--param-set", str(good)]) == 0
    assert "valid — 2 FMUs, 1 connection, 1 parameter value" in capsys.readouterr().out   # gain.k replaced


def test_quiet_prints_nothing_but_errors_and_warnings(tmp_path, twin_fmus, capsys):
    folder = _pair(tmp_path, twin_fmus, stop=2.0, step=0.5)
    assert main(["run", str(folder), "-o", str(tmp_path / "o.csv"), "--quiet", "--plot"]) == 0
    assert (tmp_path / "o.png").is_file()
    assert capsys.readouterr() == ("", "")
    assert main(["sweep", str(folder), "--set", "gain.k=1,2", "--workers", "1", "-o", str(tmp_path / "sw"),
                 "-q"]) == 0
    assert capsys.readouterr() == ("", "")
    assert main(["run", str(folder), "-o", str(tmp_path / "o.csv")]) == 0
    assert "cosim: results:" in capsys.readouterr().out      # without --quiet, it says what it wrote


def test_no_progress_bar_in_a_log_file(tmp_path, twin_fmus):
    """stderr a file, not a terminal: no tqdm bar (its '\\r'-separated frames) even on a long run."""
    folder = _pair(tmp_path, twin_fmus, stop=60.0, step=0.001)   # 60 000 steps: a few s, past tqdm's 1 s delay
    log = tmp_path / "log.txt"
    with log.open("w") as err:
        done = subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(folder), "-o", str(tmp_path / "o.csv"),
                               "--kernel", "python"], stderr=err, stdout=subprocess.DEVNULL, timeout=300)
    assert done.returncode == 0
    assert "\r" not in log.read_text() and "step/s" not in log.read_text()


def test_a_single_fmus_output_interval_is_blamed_on_that_option(tmp_path, twin_fmus, capsys):
    assert main(["run", str(twin_fmus["Gain"]), "--output-interval", "-1", "-o", str(tmp_path / "o.csv")]) == 2
    assert capsys.readouterr().err.startswith("cosim: error: --output-interval -1: the step size must be a positive")
