"""The tests of tests/cosim/test_metrics.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

from cosim.cli import main


def test_metrics_cli_on_a_real_run(tmp_path, capsys):
    csv = tmp_path / "r.csv"
    assert main(["run", "ssp/pid_fopdt", "-q", "-o", str(csv), "--stop", "150"]) == 0
    capsys.readouterr()
    assert main(["metrics", str(csv), "--signal", "plant.y", "--setpoint", "setpoint.y", "--json"]) == 0
    import json
    m, = json.loads(capsys.readouterr().out)       # one event: the set-point step at 10 s
    assert 30 < m["overshoot"] < 37 and 0 < m["settling_time"] < 140
    assert main(["metrics", str(csv), "--signal", "plant.yy", "--setpoint", "setpoint.y"]) == 2
    assert "no signal matches 'plant.yy'" in capsys.readouterr().err
