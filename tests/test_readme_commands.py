"""The README's commands and the first-hour page's, extracted and run as a newcomer would, so they
cannot rot.

Every ``bash`` block of the README's "Two commands" section and of docs/first-hour.md ("Your
first hour", the documentation site's page) is run, in order, in one bash shell
(``set -euo pipefail``) in a copy of this repository (the files git tracks or would track, with
their times, and the FMUs already built).  Command 2,
``bash tests/run.sh``, is left out: it is the command that runs this suite (CI runs exactly
it).

By default command 1's ``python3 -m venv .venv`` runs over a ``.venv`` prepared to see the
packages of the environment running the tests (a ``.pth`` file), so ``pip install -e .`` and
the other installs find everything present and the test costs seconds, not a 700 MB install.
With ``COSIM_README=fresh`` nothing is prepared: the commands make a new ``.venv`` from the
``python3`` on PATH outside this environment and install from the registry, as on a new
machine (about a minute here, with the registry's files cached).

Every test runs twice (issue 25): with ``python3`` the interpreter running the tests, and with
``python3`` Debian's ``/usr/bin/python3`` (which links libpython statically), its prepared
``.venv`` seeing the packages of the cached venv of tests/pythons.py; skipped where there is no
such Python.
"""
from __future__ import annotations

import csv
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pythons import DEBIAN_PYTHON

ROOT = Path(__file__).resolve().parents[1]
# (page, heading of its section; None: the whole page)
SECTIONS = ((ROOT / "README.md", "## Two commands"), (ROOT / "docs" / "first-hour.md", None))
FRESH = os.environ.get("COSIM_README") == "fresh"


def readme_commands() -> list[str]:
    """The bash blocks of the SECTIONS, comments and ``bash tests/run.sh`` left out."""
    commands = []
    for page, heading in SECTIONS:
        section = text = page.read_text()
        if heading is not None:
            start = text.index(heading + "\n")
            end = text.find("\n## ", start + len(heading))
            section = text[start:end if end >= 0 else len(text)]
        for block in re.findall(r"```bash\n(.*?)```", section, flags=re.S):
            commands += [line for line in block.splitlines()
                         if line.strip() and not line.lstrip().startswith("#") and line.strip() != "bash tests/run.sh"]
    return commands


def _copy_repository(dest: Path) -> None:
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.split("\0")
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)
    if (ROOT / "build" / "fmus").is_dir() and not FRESH:   # built FMUs stay newer than the copied sources
        # not the .partial files of a build under way in another test worker (os.replace'd away)
        shutil.copytree(ROOT / "build" / "fmus", dest / "build" / "fmus", ignore=shutil.ignore_patterns(".*"))


def _purelib(python: str) -> str:
    return subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()


def _reuse_environment(clone: Path, python: str) -> None:
    """A .venv whose site-packages see the packages of ``python``'s environment (site.addsitedir via .pth)."""
    subprocess.run([python, "-m", "venv", "--without-pip", str(clone / ".venv")], check=True)
    target = Path(_purelib(str(clone / ".venv" / "bin" / "python")))
    (target / "zz_reuse_test_environment.pth").write_text(f"{_purelib(python)}\n")


@pytest.fixture(scope="module", params=["default", "debian"])
def newcomer(request, tmp_path_factory):
    """The README's and first-hour page's commands run in a copy of the repository; returns (clone, output)."""
    commands = readme_commands()
    clone = tmp_path_factory.mktemp("clone")
    _copy_repository(clone)
    bin_dir = str(Path(sys.executable).parent)
    path = [p for p in os.environ["PATH"].split(os.pathsep) if p != bin_dir]
    if request.param == "debian":       # python3 is Debian's, found first on PATH
        environment = request.getfixturevalue("debian_python")
        shim = tmp_path_factory.mktemp("debian-python3")
        (shim / "python3").symlink_to(DEBIAN_PYTHON)
        bin_dir = str(shim)
    else:
        environment = Path(sys.executable)
    if not FRESH:
        _reuse_environment(clone, str(environment))
    if request.param == "debian" or not FRESH:
        path.insert(0, bin_dir)          # python3 is the chosen one, as a user's would be theirs
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTEST_ADDOPTS")}
    env.update(PATH=os.pathsep.join(path), MPLBACKEND="Agg", PIP_DISABLE_PIP_VERSION_CHECK="1")
    script = "set -euo pipefail\n" + "\n".join(commands) + "\n"
    done = subprocess.run(["bash", "-c", script], cwd=clone, env=env, capture_output=True, text=True,
                          timeout=1800)
    output = done.stdout + done.stderr
    assert done.returncode == 0, f"README commands failed (exit {done.returncode}):\n{script}\n{output[-6000:]}"
    return clone, output


def test_the_readme_has_the_first_hour_commands():
    commands = readme_commands()
    steps = [c.split("#")[0].strip() for c in commands[:5]]
    assert steps == ['PY=$(command -v python3 || command -v python)', '"$PY" -m venv .venv', ". .venv/bin/activate",
                     "python -m pip install -q -e .", "cosim run ssp/pid_fopdt --plot --report"]
    assert all(len(c) <= 110 for c in commands[:5])      # issue 27: one step a line, short enough to read
    for step in ("cosim metrics", "--param-set", "ssp/pid_mass_damper", "cosim sweep", "cosim-update-references"):
        assert any(step in c for c in commands), step


@pytest.mark.slow   # 80 s on the shared 2-core machine (build/test-durations.json)
def test_command_1_installs_into_the_venv_and_writes_results_plot_and_report(newcomer):
    clone, output = newcomer
    for suffix in (".csv", ".json", ".png", ".html"):
        assert (clone / "results" / f"pid_fopdt{suffix}").stat().st_size > 0, suffix
    assert "cosim: report: results/pid_fopdt.html" in output
    assert (clone / ".venv" / "bin" / "cosim").is_file()         # the console script is the venv's own


def test_metrics_give_one_row_per_event(newcomer):
    _, output = newcomer
    rows = re.findall(r"^  (\d) (set-point setpoint\.y 0 → 1|disturbance load\.y 0 → -1) +\S+ +(.*)$", output, re.M)
    assert [r[:2] for r in rows] == [("1", "set-point setpoint.y 0 → 1"), ("2", "disturbance load.y 0 → -1")]
    overshoot = float(rows[0][2].split()[3])
    assert 33 <= overshoot < 34                                    # docs/first-hour.md says 33 %


def test_parameter_sets_and_the_third_party_plant_get_their_own_results(newcomer):
    clone, _ = newcomer
    results = clone / "results"
    assert (results / "pid_fopdt__pi_only.png").is_file() and (results / "pid_fopdt__pi_only.csv").is_file()
    assert (results / "pid_mass_damper.png").is_file()


def test_the_sweep_is_a_closed_loop_with_finite_metrics_as_the_readme_says(newcomer):
    clone, _ = newcomer
    with open(clone / "results" / "pid_fopdt_sweep" / "sweep.csv") as f:
        rows = sorted(csv.DictReader(f), key=lambda r: float(r["controller.Kc"]))
    assert [float(r["controller.Kc"]) for r in rows] == [4, 6, 8]
    assert all(r["status"] == "completed" and r["undefined(plant.y)"] == "" for r in rows)
    overshoot = [float(r["plant.y:overshoot"]) for r in rows]
    rise = [float(r["plant.y:rise_time"]) for r in rows]
    settling = [float(r["plant.y:settling_time"]) for r in rows]
    assert round(overshoot[0]) == 23 and round(overshoot[-1]) == 34 and overshoot == sorted(overshoot)
    assert (rise[0], rise[-1]) == (pytest.approx(16.4), pytest.approx(8.8))
    assert (round(settling[0]), round(settling[-1])) == (106, 72)


def test_the_regression_test_writes_then_checks_its_reference(newcomer):
    clone, output = newcomer
    assert (clone / "my_tests" / "test_my_loop" / "test_my_loop.csv").is_file()   # beside the user's test file
    assert not (clone / "tests" / "references" / "test_my_loop.csv").exists()      # not in greyfmu's own tests
    assert len(re.findall(r"^1 passed", output, re.M)) == 2


def test_the_venv_is_made_from_the_python3_on_path(newcomer, request):
    """The Debian variant really runs Debian's interpreter: the venv's python is /usr/bin/python3."""
    clone, _ = newcomer
    chosen = DEBIAN_PYTHON if request.node.callspec.params["newcomer"] == "debian" else Path(sys.executable)
    assert (clone / ".venv" / "bin" / "python").resolve() == chosen.resolve()
