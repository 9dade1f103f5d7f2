"""Algebraic loops the fixed point cannot solve in its budget, solved by Newton's method
(`cosim.run.loops`, MINPACK hybrd through scipy.optimize.root; issue 30, item 5), on C FMUs
compiled here (tests/cfmus.py) with true direct feedthrough:

* a nested loop of two blocks, A: ya = 1 + t + 0.6 a1 + 0.35 a2 and B: z1 = b,
  z2 = b + 0.1 sin b, wired ya -> b, z1 -> a1, z2 -> a2 (two cycles through both blocks):
  the sweeps contract by 0.915..0.985, some 500 of them to 1e-10, so the fixed point fails
  at its default 100 and converges with 1000;
* a stiff crane-like loop at its own step 1e-4: a mass whose velocity output feeds through
  the force it is given over the coming step (v = v0 + Δv + dt F / m, Δv += h F / m in the
  step) and a stiff damper-spring
  (F = -k x - c v); the loop gain c dt / m = 20 makes every sweep 20 times larger;
* a block that returns NaN from finite inputs inside the iteration: named, not reported as
  a convergence failure; one that returns NaN only outside its domain, which the diverging
  sweeps reach: Newton takes over from the best sweep and solves the loop.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import cosim
from cfmus import build_c_fmu, fmi2_description
from cosim.errors import RunError
from cosim.run.loops import LoopSettings
from ssdgen import ssd_text, write_system

#: name -> (variables (name, value reference, causality, start), dependencies, C body)
MODELS = {
    "A": ([("a1", 0, "input", 0.0), ("a2", 1, "input", 0.0), ("ya", 2, "output", None)], {"ya": ["a1", "a2"]},
          "static void start(S *s) { }\n"
          "static void calculate(S *s) { s->r[2] = 1.0 + s->time + 0.6 * s->r[0] + 0.35 * s->r[1]; }\n"
          "static int step(S *s, double t, double h) { return 0; }\n"),
    "B": ([("b", 0, "input", 0.0), ("z1", 1, "output", None), ("z2", 2, "output", None)], {"z1": ["b"], "z2": ["b"]},
          "#include <math.h>\n"
          "static void start(S *s) { }\n"
          "static void calculate(S *s) { s->r[1] = s->r[0]; s->r[2] = s->r[0] + 0.1 * sin(s->r[0]); }\n"
          "static int step(S *s, double t, double h) { return 0; }\n"),
    "Mass": ([("F", 0, "input", 0.0), ("v", 1, "output", None), ("m", 2, "parameter", 1.0),
              ("dt", 3, "parameter", 1e-4), ("v0", 4, "parameter", 1.0)], {"v": ["F"]},
             "static void start(S *s) { s->r[2] = 1.0; s->r[3] = 1e-4; s->r[4] = 1.0; }\n"
             "static void calculate(S *s) { s->r[1] = s->r[4] + s->r[5] + s->r[3] * s->r[0] / s->r[2]; }\n"
             "static int step(S *s, double t, double h) { s->r[5] += h * s->r[0] / s->r[2]; return 0; }\n"),
    "Damper": ([("v", 0, "input", 0.0), ("F", 1, "output", None), ("k", 3, "parameter", 1.0),
                ("c", 4, "parameter", 1.0)], {"F": ["v"]},
               "static void start(S *s) { s->r[3] = 1.0; s->r[4] = 1.0; }\n"
               "static void calculate(S *s) { s->r[1] = -s->r[3] * s->r[2] - s->r[4] * s->r[0]; }\n"
               "static int step(S *s, double t, double h) { s->r[2] += h * s->r[0]; return 0; }\n"),
    "Half": ([("u", 0, "input", 0.0), ("y", 1, "output", None)], {"y": ["u"]},
             "#include <math.h>\n"
             "static void start(S *s) { }\n"
             "static void calculate(S *s) { s->r[1] = s->r[0] > 5.0 ? NAN : 0.5 * s->r[0] + 1.0; }\n"
             "static int step(S *s, double t, double h) { return 0; }\n"),
    "Ramp": ([("u", 0, "input", 0.0), ("y", 1, "output", None)], {"y": ["u"]},
             "static void start(S *s) { }\n"
             "static void calculate(S *s) { s->r[1] = 0.5 * s->r[0] + 100.0 * s->time; }\n"
             "static int step(S *s, double t, double h) { return 0; }\n"),
    "Steep": ([("u", 0, "input", 0.0), ("y", 1, "output", None)], {"y": ["u"]},
              "#include <math.h>\n"
              "static void start(S *s) { }\n"
              "static void calculate(S *s) { s->r[1] = fabs(s->r[0]) > 50.0 ? NAN : -30.0 * s->r[0] + 1.0; }\n"
              "static int step(S *s, double t, double h) { return 0; }\n"),
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("newtonfmus")
    return {name: build_c_fmu(tmp, name, fmi2_description(name, variables, deps, "{7a0c0000-0000-4000-8000-%012x}"
                                                          % sum(map(ord, name))), body)
            for name, (variables, deps, body) in MODELS.items()}


def _system(tmp_path, fmus, comps, wires, stop, step, parameters=None):
    files = {f: fmus[f.removesuffix(".fmu")] for f, _ in comps.values()}
    text = ssd_text("loop", comps, wires, stop=stop, step=step, parameters=parameters)
    return write_system(tmp_path / "s", files, text)


def _meta(out):
    return json.loads(out.with_suffix(".json").read_text())["algebraic_loops"]


NESTED = {"a": ("A.fmu", {"a1": "input", "a2": "input", "ya": "output"}),
          "b": ("B.fmu", {"b": "input", "z1": "output", "z2": "output"})}
NESTED_WIRES = [("a", "ya", "b", "b"), ("b", "z1", "a", "a1"), ("b", "z2", "a", "a2")]


def test_a_nested_loop_the_fixed_point_needs_1000_sweeps_for_converges_by_newton(tmp_path, fmus):
    folder = _system(tmp_path, fmus, NESTED, NESTED_WIRES, stop=0.05, step=0.01)
    with pytest.raises(RunError, match=r"did not converge at t = 0: after 100 iterations"):
        cosim.simulate(folder, loop_settings=LoopSettings(method="fixed-point"))
    out = tmp_path / "newton.csv"
    ours = cosim.simulate(folder, output=out)
    meta = _meta(out)
    slow = cosim.simulate(folder, loop_settings=LoopSettings(method="fixed-point", max_iterations=1000))
    for row in ours:  # 0.05 ya − 0.035 sin ya = 1 + t
        exact = brentq(lambda y, t=row["time"]: 0.05 * y - 0.035 * math.sin(y) - 1 - t, 0.0, 100.0, xtol=1e-14)
        assert row["a.ya"] == pytest.approx(exact, rel=1e-9)
        assert row["b.z2"] == pytest.approx(exact + 0.1 * math.sin(exact), rel=1e-9)
    np.testing.assert_allclose(ours["a.ya"], slow["a.ya"], rtol=1e-8)
    assert meta["newton_solves"] >= len(ours) and meta["fallbacks"] == 0
    assert meta["iterations_max"] <= 20 and meta["residual_max"] <= 1.0   # the fixed point: some 500


CRANE = {"mass": ("Mass.fmu", {"F": "input", "v": "output"}), "damper": ("Damper.fmu", {"v": "input", "F": "output"})}
CRANE_WIRES = [("mass", "v", "damper", "v"), ("damper", "F", "mass", "F")]
M, C, K, DT = 1.0, 2e5, 1e3, 1e-4


def _crane_reference(n: int) -> np.ndarray:
    """v at each communication point: v = (v_s − dt k x / m) / (1 + dt c / m), then
    v_s += dt F / m, x += dt v (the loop solved exactly at every point)."""
    vs, x, out = 1.0, 0.0, []
    for _ in range(n):
        v = (vs - DT * K * x / M) / (1 + DT * C / M)
        out.append(v)
        force = -K * x - C * v
        vs, x = vs + DT * force / M, x + DT * v
    return np.array(out)


def test_a_stiff_crane_like_loop_runs_at_its_own_step(tmp_path, fmus):
    values = {"mass": {"m": M, "dt": DT, "v0": 1.0}, "damper": {"k": K, "c": C}}
    folder = _system(tmp_path, fmus, CRANE, CRANE_WIRES, stop=0.02, step=DT, parameters=values)
    with pytest.raises(RunError, match=r"algebraic loop did not converge at t = 0: after 100 iterations"):
        cosim.simulate(folder, loop_settings=LoopSettings(method="fixed-point"))
    out = tmp_path / "o.csv"
    ours = cosim.simulate(folder, output=out)
    assert len(ours) == 201
    reference = _crane_reference(len(ours))
    np.testing.assert_allclose(ours["mass.v"], reference, rtol=1e-8, atol=1e-12)
    assert abs(ours["mass.v"][-1]) < 1e-6 * abs(ours["mass.v"][0])     # damped, not diverged
    meta = _meta(out)
    assert meta["newton_solves"] >= len(ours) - 1 and meta["fallbacks"] == 0
    # after the first point, one sweep, a two-sweep Jacobian and a step or two (the first: three sweeps more)
    assert meta["iterations_max"] <= 20 and meta["iterations_total"] / meta["solves"] <= 6


NAN_LOOP = {"n": ("Half.fmu", {"u": "input", "y": "output"}), "r": ("Ramp.fmu", {"u": "input", "y": "output"})}
NAN_WIRES = [("n", "y", "r", "u"), ("r", "y", "n", "u")]


@pytest.mark.parametrize("method", ["newton", "fixed-point"])
def test_a_nan_inside_the_iteration_names_the_fmu_the_variable_and_t(tmp_path, fmus, method):
    """n.y = 0.5 r.y + 1 while r.y <= 5, NaN above; r.y = 0.5 n.y + 100 t: r.y passes 5 after
    t = 0.0325, so the first sweep at t = 0.04 gives n finite inputs and gets NaN back."""
    folder = _system(tmp_path, fmus, NAN_LOOP, NAN_WIRES, stop=0.1, step=0.01)
    with pytest.raises(RunError) as err:
        cosim.simulate(folder, loop_settings=LoopSettings(method=method))
    message = str(err.value)
    assert message.startswith("component 'n': output 'y' is nan at t = 0.04 (in iteration 1 of the algebraic loop")
    assert "converge" not in message and err.value.time == pytest.approx(0.04)


def test_cli_runs_the_nested_loop_with_either_method(tmp_path, fmus, capsys):
    from cosim.cli import main

    folder = _system(tmp_path, fmus, NESTED, NESTED_WIRES, stop=0.05, step=0.01)
    assert main(["run", str(folder), "-o", str(tmp_path / "n.csv"), "-q"]) == 0
    assert _meta(tmp_path / "n.csv")["method"].endswith("where the sweeps are slow or diverge")
    assert main(["run", str(folder), "-o", str(tmp_path / "f.csv"), "-q", "--loop-method", "fixed-point"]) == 1
    assert "did not converge at t = 0: after 100 iterations" in capsys.readouterr().err
    assert main(["run", str(folder), "-o", str(tmp_path / "g.csv"), "-q", "--loop-method", "fixed-point",
                 "--loop-iterations", "1000"]) == 0


STEEP_LOOP = {"p": ("Steep.fmu", {"u": "input", "y": "output"}), "r": ("Ramp.fmu", {"u": "input", "y": "output"})}
STEEP_WIRES = [("p", "y", "r", "u"), ("r", "y", "p", "u")]


def test_sweeps_that_diverge_out_of_an_fmus_domain_are_taken_over_by_newton(tmp_path, fmus):
    """p.y = −30 r.y + 1 (NaN for |r.y| > 50), r.y = 0.5 p.y + 100 t: the sweeps grow 15-fold and
    leave p's domain within a few, from the first solve (t = 0, inputs at 0); the answer
    p.y = (1 − 3000 t) / 16 is inside it."""
    folder = _system(tmp_path, fmus, STEEP_LOOP, STEEP_WIRES, stop=0.1, step=0.01)
    with pytest.raises(RunError, match=r"component 'p': output 'y' is nan at t = 0 \(in iteration [2-9]"):
        cosim.simulate(folder, loop_settings=LoopSettings(method="fixed-point"))
    out = tmp_path / "o.csv"
    ours = cosim.simulate(folder, output=out)
    np.testing.assert_allclose(ours["p.y"], (1 - 3000 * ours["time"]) / 16, rtol=1e-9, atol=1e-12)
    assert _meta(out)["newton_solves"] >= len(ours) - 1
