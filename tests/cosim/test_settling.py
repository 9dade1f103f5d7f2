"""The exchange's shortcuts in settling direct feedthrough (cosim.plan.graph.settling_shortcuts):
which FMI calls are left out, and that leaving them out changes no value."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cosim.plan.prepare import prepare
from cosim.run import simulation
from cosim.model.transforms import IDENTITY
from cosim.plan.graph import Route, settling_shortcuts
from ssdgen import ssd_text, write_system


def _routes(*pairs: tuple[str, str]) -> list[Route]:
    return [Route(src, None, dst, None, IDENTITY) for src, dst in pairs]


def test_a_chain_is_read_and_set_once_per_block():
    # plant -> g1 -> g2 -> sum -> plant (the plant has no feedthrough, so the loop is not algebraic)
    routes = _routes(("plant", "g1"), ("g1", "g2"), ("g2", "sum"), ("sum", "plant"))
    read_once, set_once = settling_shortcuts(["g1", "g2", "sum"], routes)
    assert read_once == {"g1", "g2", "sum"} and set_once == {"g1", "g2", "sum"}


def test_a_block_read_before_its_place_or_fed_after_it_keeps_its_calls():
    # "a" settles twice (two of its outputs depend on different inputs) around "b":
    # a reads b at its first place, before b is re-read, so b's first read stays; b reads a
    # at its only place, before a's last, so b is set again at the end; a is set with final
    # values at its last place
    read_once, set_once = settling_shortcuts(["a", "b", "a"], _routes(("a", "b"), ("b", "a")))
    assert read_once == {"a"} and set_once == {"a"}
    # a block that reads itself back keeps both calls
    read_once, set_once = settling_shortcuts(["a"], _routes(("a", "a")))
    assert read_once == set() and set_once == set()


@pytest.fixture
def feedthrough_loop(tmp_path, twin_fmus):
    """Step -> Sum(+ feedback) -> Gain -> Gain -> FirstOrderFilter -> back into the Sum."""
    components = {"r": ("Step.fmu", {"y": "output"}),
                  "sum": ("Sum.fmu", {"u1": "input", "u2": "input", "y": "output"}),
                  "g1": ("Gain.fmu", {"u": "input", "y": "output"}),
                  "g2": ("Gain.fmu", {"u": "input", "y": "output"}),
                  "lag": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    connections = [("r", "y", "sum", "u1"), ("sum", "y", "g1", "u"), ("g1", "y", "g2", "u"),
                   ("g2", "y", "lag", "u"), ("lag", "y", "sum", "u2")]
    text = ssd_text("loop", components, connections, stop=5.0, step=0.01,
                    parameters={"r": {"t_step": 0.5}, "sum": {"k2": -1.0}, "g1": {"k": 2.0}, "g2": {"k": 1.5},
                                "lag": {"T": 0.7}})
    fmus = {f"{n}.fmu": twin_fmus[n] for n in ("Step", "Sum", "Gain", "FirstOrderFilter")}
    return write_system(tmp_path / "sys", fmus, text)


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_the_shortcuts_change_no_value(feedthrough_loop, algorithm):
    results = []
    for shortcuts in (True, False):
        prepared = prepare(feedthrough_loop, algorithm=algorithm)
        try:
            assert prepared.plan.read_in_settling_only == {"sum", "g1", "g2"}
            if not shortcuts:  # the Plan is frozen: a copy without the shortcuts
                prepared = dataclasses.replace(prepared, plan=dataclasses.replace(
                    prepared.plan, read_in_settling_only=set(), set_in_settling_only=set()))
            result, _ = simulation.run(prepared)
        finally:
            prepared.close()
        results.append(result)
    with_shortcuts, without = results
    for name in with_shortcuts.dtype.names:
        np.testing.assert_array_equal(with_shortcuts[name], without[name], err_msg=name)
    # the loop settles within the instant: u = r - y_lag through the gains at every sample
    expected = 3.0 * (with_shortcuts["r.y"] - with_shortcuts["lag.y"])
    np.testing.assert_allclose(with_shortcuts["g2.y"], expected, rtol=0, atol=1e-12)
