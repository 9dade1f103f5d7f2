"""A 10 000-FMU feedthrough chain validates (issue 17: `graph.tarjan` was recursive and a
chain of ~1000 FMUs raised RecursionError)."""
from __future__ import annotations

import pytest

from cosim.cli import main
from cosim.plan.graph import tarjan, topological
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus


def test_tarjan_and_topological_order_a_deep_chain_without_recursion():
    nodes = list(range(100_000))
    edges = {i: [i + 1] for i in range(len(nodes) - 1)}
    assert tarjan(nodes, edges) == [[i] for i in reversed(nodes)]
    assert topological(nodes, edges) == nodes
    edges[len(nodes) - 1] = [0]  # close the ring: one component of every node
    assert [sorted(c) for c in tarjan(nodes, edges)] == [nodes]


def test_tarjan_matches_the_textbook_example():
    # Cormen et al. fig. 22.9: components {a,b,e}, {c,d}, {f,g}, {h}
    edges = {"a": ["b"], "b": ["c", "e", "f"], "c": ["d", "g"], "d": ["c", "h"], "e": ["a", "f"],
             "f": ["g"], "g": ["f", "h"], "h": ["h"]}
    assert [sorted(c) for c in tarjan(list("abcdefgh"), edges)] == [["h"], ["f", "g"], ["c", "d"], ["a", "b", "e"]]


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


N = 10_000


@pytest.mark.pythonfmu
def test_a_10000_fmu_feedthrough_chain_validates(tmp_path_factory, capsys):
    fmus = build_test_fmus(tmp_path_factory.mktemp("chainfmus"))
    comps = {f"c{i}": ("Failing.fmu", {"u": "input", "y": "output"}) for i in range(N)}
    connections = [(f"c{i}", "y", f"c{i + 1}", "u") for i in range(N - 1)]
    folder = write_system(tmp_path_factory.mktemp("chain") / "sys", {"Failing.fmu": fmus["Failing"]},
                          ssd_text("chain", comps, connections))
    assert main(["validate", str(folder)]) == 0, capsys.readouterr().err
    assert f"valid — {N} FMUs, {N - 1} connections" in capsys.readouterr().out
