"""One CLI truth (issue 27, item 3): the README's synopsis and each subcommand's --help name the
same options, the help says what the code does, and the command line's own values, --quiet,
the progress bar, --version and shell completion behave as documented."""
from __future__ import annotations

import argparse
import re
from importlib.metadata import version
from pathlib import Path

import pytest

from cosim.cli import _parser, main

ROOT = Path(__file__).resolve().parents[2]
OPTION = r"(?<![\w-])(--?[a-z][a-z0-9-]*)"


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    return next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction)).choices


def _synopsis() -> dict[str, set[str]]:
    """The options of each `cosim SUB` of the README's synopsis block (## The master), comments left out."""
    block = (ROOT / "README.md").read_text().split("## The master", 1)[1].split("```", 2)[1]
    options: dict[str, set[str]] = {}
    current = None
    for line in block.splitlines():
        start = re.match(r"cosim (\w+)", line)
        current = start.group(1) if start else (current if line.startswith(" ") else None)
        if current:
            options.setdefault(current, set()).update(re.findall(OPTION, line.split("#")[0]))
    return options


@pytest.mark.parametrize("name", sorted(_subcommands()))
def test_readme_synopsis_and_help_name_the_same_options(name):
    """Every option the README gives a subcommand exists, and every option of its --help is in the README
    (an option with an alias, e.g. --stop/--stop-time, by any of its names)."""
    documented = _synopsis().get(name, set())
    actions = [a for a in _subcommands()[name]._actions
               if a.option_strings and a.help != argparse.SUPPRESS and "--help" not in a.option_strings]
    known = {o for a in actions for o in a.option_strings}
    assert documented <= known, f"cosim {name}: the README names options it lacks: {sorted(documented - known)}"
    missing = [a.option_strings for a in actions if not documented & set(a.option_strings)]
    assert not missing, f"cosim {name}: options of --help the README does not document: {missing}"


def test_help_says_what_the_code_does(capsys):
    """--threads is implemented (cosim.execution, the compiled kernel's pool); cosim runs more than
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
