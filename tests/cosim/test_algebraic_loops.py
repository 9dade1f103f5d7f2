"""Algebraic loops of direct feedthrough (issue 21, item 8; `cosim.run.loops`), on C FMUs
compiled here (tests/cfmus.py) whose outputs omit ``dependencies``, as 20-sim's and many
third-party plant FMUs do (FMI 2.0 §2.2.8 then makes them depend on every input).

* a quarter-truck-like chain (chassis and wheel masses, suspension and tyre springs) and a
  crane-like loop (a PD controller on a mass): no true algebraic loop, only the declared
  one; solved by iteration they equal the same FMUs with their true dependencies, and
  with ``loops="delay"`` they equal libcosim (which runs every connection one step late);
* a true loop of two affine blocks, y1 = a1 y2 + b1, y2 = a2 y1 + b2: the solution, the
  iteration count and residual in the metadata, the failure when it diverges, and the
  relaxation that makes it converge.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu, fmi2_description
from cosim.errors import RunError
from cosim.run.loops import LoopSettings
from ssdgen import ssd_text, write_system

H, STOP = 0.01, 2.0


def model_description(name: str, variables: list[tuple[str, int, str, float | None]], omit_dependencies: bool,
                      true_dependencies: dict[str, str] | None = None) -> str:
    """FMI 2.0 CS model description: (name, value reference, causality, start); outputs list
    no ``dependencies`` (omit_dependencies) or their true ones (names of inputs)."""
    guid = "{7a0c%04x-0000-4000-8000-%012x}" % (len(name), sum(map(ord, name)) + (0 if omit_dependencies else 1))
    dependencies = None if omit_dependencies else {out: ins.split() for out, ins in (true_dependencies or {}).items()}
    return fmi2_description(name, variables, dependencies, guid)


#: (variables, true dependencies, C body); value references index s->r
MODELS = {
    "Mass": ([("F1", 0, "input", 0.0), ("F2", 5, "input", 0.0), ("x", 1, "output", None),
              ("v", 2, "output", None), ("m", 3, "parameter", 1.0)], {},
             "static void start(S *s) { s->r[3] = 1.0; }\n"
             "static void calculate(S *s) {}\n"
             "static int step(S *s, double t, double h) {\n"
             "    s->r[2] += h * (s->r[0] + s->r[5]) / s->r[3]; s->r[1] += h * s->r[2]; return 0; }\n"),
    "Spring": ([("xa", 0, "input", 0.0), ("xb", 1, "input", 0.0), ("Fa", 2, "output", None),
                ("Fb", 3, "output", None), ("k", 4, "parameter", 1.0)], {"Fa": "xa xb", "Fb": "xa xb"},
               "static void start(S *s) { s->r[4] = 1.0; }\n"
               "static void calculate(S *s) { s->r[2] = s->r[4] * (s->r[1] - s->r[0]); s->r[3] = -s->r[2]; }\n"
               "static int step(S *s, double t, double h) { return 0; }\n"),
    "PD": ([("x", 0, "input", 0.0), ("v", 1, "input", 0.0), ("F", 2, "output", None), ("r", 3, "parameter", 1.0),
            ("kp", 4, "parameter", 1.0), ("kd", 5, "parameter", 1.0)], {"F": "x v"},
           "static void start(S *s) { s->r[3] = 1.0; s->r[4] = 1.0; s->r[5] = 1.0; }\n"
           "static void calculate(S *s) { s->r[2] = s->r[4] * (s->r[3] - s->r[0]) - s->r[5] * s->r[1]; }\n"
           "static int step(S *s, double t, double h) { return 0; }\n"),
    "Affine": ([("u", 0, "input", 0.0), ("y", 1, "output", None), ("a", 2, "parameter", 1.0),
                ("b", 3, "parameter", 0.0)], {"y": "u"},
               "static void start(S *s) { s->r[2] = 1.0; }\n"
               "static void calculate(S *s) { s->r[1] = s->r[2] * s->r[0] + s->r[3]; }\n"
               "static int step(S *s, double t, double h) { return 0; }\n"),
}


@pytest.fixture(scope="module")
def cfmus(tmp_path_factory):
    """Each model twice: outputs without dependencies (the loop case) and with their true ones."""
    tmp = tmp_path_factory.mktemp("loopfmus")
    built = {}
    for name, (variables, deps, body) in MODELS.items():
        built[name] = build_c_fmu(tmp / "omit", name, model_description(name, variables, True), body)
        built[name + "_true"] = build_c_fmu(tmp / "true", name, model_description(name, variables, False, deps), body)
    return built


MASS = {"F1": "input", "F2": "input", "x": "output", "v": "output"}
SPRING = {"xa": "input", "xb": "input", "Fa": "output", "Fb": "output"}
TRUCK = {"chassis": ("Mass.fmu", MASS), "suspension": ("Spring.fmu", SPRING), "wheel": ("Mass.fmu", MASS),
         "tyre": ("Spring.fmu", SPRING)}
TRUCK_WIRES = [("chassis", "x", "suspension", "xa"), ("wheel", "x", "suspension", "xb"),
               ("suspension", "Fa", "chassis", "F1"), ("suspension", "Fb", "wheel", "F1"),
               ("wheel", "x", "tyre", "xa"), ("tyre", "Fa", "wheel", "F2")]
TRUCK_VALUES = {"chassis": {"m": 10.0}, "wheel": {"m": 1.0}, "suspension": {"k": 100.0},
                "tyre": {"k": 1000.0, "xb": 0.05}}     # the road 5 cm up from t = 0
CRANE = {"boom": ("Mass.fmu", MASS), "controller": ("PD.fmu", {"x": "input", "v": "input", "F": "output"})}
CRANE_WIRES = [("boom", "x", "controller", "x"), ("boom", "v", "controller", "v"), ("controller", "F", "boom", "F1")]
CRANE_VALUES = {"boom": {"m": 2.0}, "controller": {"r": 1.0, "kp": 8.0, "kd": 4.0}}
SYSTEMS = {"quarter_truck": (TRUCK, TRUCK_WIRES, TRUCK_VALUES), "crane": (CRANE, CRANE_WIRES, CRANE_VALUES)}


def _system(folder, cfmus, system: str, true_dependencies: bool = False, typed: bool = False):
    comps, wires, values = SYSTEMS[system]
    text = ssd_text(system, comps, wires, stop=STOP, step=H, parameters=values)
    if typed:  # libcosim needs a type element on every connector
        text = text.replace('kind="input"/>', 'kind="input"><ssc:Real/></ssd:Connector>') \
                   .replace('kind="output"/>', 'kind="output"><ssc:Real/></ssd:Connector>')
    suffix = "_true" if true_dependencies else ""
    files = {f: cfmus[f.removesuffix(".fmu") + suffix] for f, _ in comps.values()}
    return write_system(folder, files, text)


def _outputs(system: str) -> list[str]:
    return [f"{c}.{n}" for c, (_, connectors) in SYSTEMS[system][0].items()
            for n, kind in connectors.items() if kind == "output"]


@pytest.mark.parametrize("system", ["quarter_truck", "crane"])
def test_declared_loops_solved_by_iteration_equal_the_true_dependencies(tmp_path, cfmus, system):
    out = tmp_path / "o.csv"
    ours = cosim.simulate(_system(tmp_path / "omit", cfmus, system), output=out)
    meta = json.loads(out.with_suffix(".json").read_text())["algebraic_loops"]
    truth = cosim.simulate(_system(tmp_path / "true", cfmus, system, true_dependencies=True))
    for name in _outputs(system):
        np.testing.assert_array_equal(ours[name], truth[name], err_msg=name)
    assert np.ptp(ours["wheel.x" if system == "quarter_truck" else "boom.x"]) > 0.01   # it moved
    assert meta["mode"] == "iterate" and meta["loops"] and meta["rtol"] == 1e-10
    assert meta["solves"] == len(ours) + 1          # every communication point and both initial exchanges
    assert 2 <= meta["iterations_max"] <= 3 and meta["residual_max"] <= 1.0


@pytest.mark.parametrize("system", ["quarter_truck", "crane"])
def test_loops_broken_by_delay_equal_libcosim(tmp_path, cfmus, system):
    from peers import run_libcosim

    folder = _system(tmp_path / "sys", cfmus, system, typed=True)
    with pytest.warns(RuntimeWarning, match=r"algebraic loop broken by one step of delay .*\(output\) ->"):
        ours = cosim.simulate(folder, loops="delay")
    names = _outputs(system)
    theirs = run_libcosim(folder, 0.0, STOP, H, names)
    assert len(theirs) == len(ours)
    for name in names:  # to the last bits: libcosim passes t_k = k·10^7 ns / 10^9 and h_k = t_k+1 − t_k
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-12, atol=1e-12, err_msg=name)
    iterated = cosim.simulate(folder)
    assert np.max(np.abs(iterated[names[0]] - ours[names[0]])) > 0     # the delay changes the answer


AFFINE = {"u": "input", "y": "output"}


def _affine_loop(tmp_path, cfmus, a1: float, a2: float, b1: float = 1.0, b2: float = 2.0):
    comps = {"p": ("Affine.fmu", AFFINE), "q": ("Affine.fmu", AFFINE)}
    text = ssd_text("affine", comps, [("p", "y", "q", "u"), ("q", "y", "p", "u")], stop=0.05, step=H,
                    parameters={"p": {"a": a1, "b": b1}, "q": {"a": a2, "b": b2}})
    return write_system(tmp_path / f"affine{a1}_{a2}", {"Affine.fmu": cfmus["Affine_true"]}, text)


@pytest.mark.parametrize("method", ["fixed-point", "newton"])
def test_a_true_loop_converges_to_its_solution(tmp_path, cfmus, method):
    """y_p = 0.5 y_q + 1, y_q = 0.8 y_p + 2: y_p = 2/0.6, y_q = 0.8 y_p + 2; contraction 0.4 per
    sweep: some 25 sweeps, where Newton (after three sweeps judge the contraction too slow) needs
    a Jacobian (two sweeps) and a step or two."""
    out = tmp_path / "o.csv"
    res = cosim.simulate(_affine_loop(tmp_path, cfmus, 0.5, 0.8), output=out,
                         loop_settings=LoopSettings(method=method))
    np.testing.assert_allclose(res["p.y"], 2.0 / 0.6, rtol=1e-9)
    np.testing.assert_allclose(res["q.y"], 0.8 * 2.0 / 0.6 + 2.0, rtol=1e-9)
    meta = json.loads(out.with_suffix(".json").read_text())["algebraic_loops"]
    assert meta["loops"] == ["p.y (output) -> q.u (input) -> q.y (output) -> p.u (input) -> p.y (output)"] \
        or meta["loops"] == ["q.y (output) -> p.u (input) -> p.y (output) -> q.u (input) -> q.y (output)"]
    assert meta["iterations_total"] > meta["solves"] and meta["fallbacks"] == 0
    if method == "fixed-point":
        assert 15 <= meta["iterations_max"] <= 40     # 0.4^k below 1e-10 relative
        assert meta["newton_solves"] == 0
    else:
        assert meta["iterations_max"] <= 10 and meta["newton_solves"] == 1   # later solves start at the answer


def test_a_diverging_loop_fails_clearly_and_relaxation_or_newton_makes_it_converge(tmp_path, cfmus):
    """a1 a2 = -2: the plain fixed point diverges; with ω = 0.3 it contracts by |1 + 0.3 (-2 - 1)| = 0.1;
    Newton (the default) takes over once three sweeps show the divergence."""
    folder = _affine_loop(tmp_path, cfmus, 2.0, -1.0)
    with pytest.raises(RunError, match=r"algebraic loop did not converge at t = 0: after \d+ iterations") as e:
        cosim.simulate(folder, loop_settings=LoopSettings(method="fixed-point"))
    assert "p.y (output)" in str(e.value) and "--relaxation" in str(e.value)
    y_p = (2.0 * 2.0 + 1.0) / (1.0 - 2.0 * -1.0)
    for settings in (LoopSettings(method="fixed-point", relaxation=0.3), LoopSettings()):
        res = cosim.simulate(folder, loop_settings=settings)
        np.testing.assert_allclose(res["p.y"], y_p, rtol=1e-9)
        np.testing.assert_allclose(res["q.y"], -y_p + 2.0, rtol=1e-9)


def test_cli_names_the_loop_and_runs_it_both_ways(tmp_path, cfmus, capsys):
    from cosim.cli import main

    folder = _system(tmp_path / "crane", cfmus, "crane")
    assert main(["validate", str(folder)]) == 0
    printed = capsys.readouterr().out
    assert "cosim: algebraic loop (run solves it by iteration; --loops delay breaks it): " in printed
    assert "boom.x (output)" in printed
    for mode in ("iterate", "delay"):
        out = tmp_path / f"{mode}.csv"
        assert main(["run", str(folder), "-o", str(out), "-q", "--loops", mode]) == 0
        assert json.loads(out.with_suffix(".json").read_text())["algebraic_loops"]["mode"] == mode
        warned = "cosim: warning: algebraic loop broken by one step of delay" in capsys.readouterr().err
        assert warned == (mode == "delay")
    assert main(["run", str(folder), "-o", str(tmp_path / "x.csv"), "-q", "--relaxation", "0"]) == 2
    assert "the relaxation factor must be in (0, 1]; got 0.0" in capsys.readouterr().err


@pytest.mark.parametrize("system", ["quarter_truck", "crane", "affine"])
def test_the_iteration_runs_the_same_in_both_interpreters(tmp_path, cfmus, system):
    """The loop solver's sweep is one operation of the step's program, made by Python within the
    compiled loop: the same samples, sweeps and residuals as the Python interpreter."""
    folder = _affine_loop(tmp_path, cfmus, 0.5, 0.8) if system == "affine" else _system(tmp_path, cfmus, system)
    runs = {}
    for kernel in ("python", "native"):
        out = tmp_path / f"{kernel}.csv"
        runs[kernel] = (cosim.simulate(folder, output=out, kernel=kernel),
                        json.loads(out.with_suffix(".json").read_text()))
    (python, p_meta), (native, n_meta) = runs["python"], runs["native"]
    for name in python.dtype.names:
        np.testing.assert_array_equal(python[name], native[name], err_msg=name)
    assert n_meta["kernel"] == "native" and p_meta["kernel"] == "python"
    assert list(n_meta["python_operations"]) == ["an algebraic loop solved by iteration (--loops iterate, cosim.run.loops)"]
    assert n_meta["algebraic_loops"] == p_meta["algebraic_loops"] and n_meta["algebraic_loops"]["solves"] > 1
