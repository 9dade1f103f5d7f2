"""The worked example of ``cosim tune`` (docs/tuning.md, "Options and a worked example", once the
README's "Tuning"): our PID FMU tuned against the OpenModelica Mass_Damper FMU of gemseo-fmu, run as
written (in a folder with ``ssp/``), and the numbers the page states checked against what it prints
and writes."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.record.results import read
from cosim.present.metrics import step_metrics
from cosim.tune import read_evaluations

ROOT = Path(__file__).resolve().parents[3]


def _block() -> str:
    """The bash block of docs/tuning.md that tunes ssp/pid_mass_damper."""
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "docs" / "tuning.md").read_text(), flags=re.S)
    [block] = [b for b in blocks if "cosim tune ssp/pid_mass_damper" in b]
    return block


def test_the_readmes_mass_damper_tuning_runs_and_says_what_it_finds(built_fmus, tmp_path):
    pytest.importorskip("gemseo_fmu")
    (tmp_path / "ssp").symlink_to(ROOT / "ssp")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(["bash", "-c", "set -euo pipefail\n" + _block()], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    out = tmp_path / "results" / "mass_damper_tune"
    rows = read_evaluations(out)
    start, best = rows[0], min((r for r in rows if r["feasible"]), key=lambda r: r["objective"])
    assert start["controller.Kc"] == 10000.0                  # controller.ssv's PID, tried first
    assert best["objective"] < start["objective"] / 50          # docs/tuning.md: "a hundredth"
    assert best["overshoot:plant.y <= 5"] <= 5
    result = read(tmp_path / "results" / "pid_mass_damper__best.csv")
    metrics = step_metrics(result["time"], result["plant.y"], result["setpoint.y"])
    assert metrics["ITAE"] == best["objective"]
    assert (out / "tune.html").is_file() and (tmp_path / "results" / "pid_mass_damper__best.png").is_file()
