"""The tests of tests/cosim/test_graph_scale.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

from cosim.cli import main
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus


N = 10_000


def test_a_10000_fmu_feedthrough_chain_validates(tmp_path_factory, capsys):
    fmus = build_test_fmus(tmp_path_factory.mktemp("chainfmus"))
    comps = {f"c{i}": ("Failing.fmu", {"u": "input", "y": "output"}) for i in range(N)}
    connections = [(f"c{i}", "y", f"c{i + 1}", "u") for i in range(N - 1)]
    folder = write_system(tmp_path_factory.mktemp("chain") / "sys", {"Failing.fmu": fmus["Failing"]},
                          ssd_text("chain", comps, connections))
    assert main(["validate", str(folder)]) == 0, capsys.readouterr().err
    assert f"valid — {N} FMUs, {N - 1} connections" in capsys.readouterr().out
