"""Model Exchange FMUs integrated by the master (cosim.run.instances.me) on OpenModelica exports from gemseo-fmu.

Mass_Damper.fmu is m = 1 kg, c = 1e4 N/m, d = 10 N·s/m (modelDescription parameters), y = damper.s_rel
with y(0) = 0 and rest at −0.5 m: y'' + 10 y' + 1e4 (y + 0.5) = f, poles −5 ± 99.9i.  Its Co-Simulation
export integrates with explicit Euler at the communication step, whose global error is c·h + O(h²):
that is why fine CS runs at h, h/2, h/4 are compared through Richardson extrapolation, which removes the
terms in h and h² (and a test checks that the CS error does halve with h).
"""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.plan.prepare import prepare
from cosim.run import simulation
from cosim.run.execution import Execution
from cosim.run.program import compile
from cosim.record.observers import MemorySink, Recorder
from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system
from testfmus import edited_copy

ME_SCENARIO = Path("ssp/pid_mass_damper_me")
SOLVER_NS = "urn:greyfmu:ssp:solver:1.0"


@pytest.fixture(scope="module")
def gemseo() -> Path:
    return gemseo_fmu_dir()


def with_implementation(text: str, component: str, implementation: str) -> str:
    tag = f'<ssd:Component name="{component}" '
    assert text.count(tag) == 1
    return text.replace(tag, f'{tag}implementation="{implementation}" ')


def with_solver(text: str, component: str, attributes: str) -> str:
    """Add an org.greyfmu.solver annotation as the last child of a component."""
    start = text.index(f'<ssd:Component name="{component}" ')
    end = text.index("</ssd:Component>", start)
    annotation = (f'<ssd:Annotations><ssc:Annotation type="org.greyfmu.solver"><greyfmu:Solver '
                  f'xmlns:greyfmu="{SOLVER_NS}" {attributes}/></ssc:Annotation></ssd:Annotations>')
    return text[:end] + annotation + text[end:]


def force_step_system(folder: Path, built_fmus, gemseo: Path, implementation: str, *, stop: float,
                      step: float, solver: str | None = None) -> Path:
    """Step.fmu (0 → 1000 N at t = 0.1 s) driving Mass_Damper.f."""
    text = ssd_text("force_step", {"force": ("Step.fmu", {"y": "output"}),
                                   "plant": ("Mass_Damper.fmu", {"f": "input", "y": "output"})},
                    [("force", "y", "plant", "f")], stop=stop, step=step,
                    parameters={"force": {"t_step": 0.1, "initial": 0.0, "final": 1000.0}})
    text = with_implementation(text, "plant", implementation)
    if solver is not None:
        text = with_solver(text, "plant", solver)
    return write_system(folder, {"Step.fmu": built_fmus["Step"], "Mass_Damper.fmu": gemseo / "Mass_Damper.fmu"},
                        text)


def mass_damper_analytic(t: np.ndarray, t_step: float, force: float) -> np.ndarray:
    """y(t) of y'' + 10 y' + 1e4 (y + 0.5) = f, y(0) = y'(0) = 0, f = 0 then `force` from t_step."""
    w, zeta = 100.0, 10.0 / (2 * 100.0)
    wd = w * np.sqrt(1 - zeta ** 2)

    def free(tau, e0, v0):  # deviation from the equilibrium and its rate
        decay = np.exp(-zeta * w * tau)
        e = decay * (e0 * np.cos(wd * tau) + (v0 + zeta * w * e0) / wd * np.sin(wd * tau))
        v = decay * (v0 * np.cos(wd * tau) - (zeta * w * v0 + w * w * e0) / wd * np.sin(wd * tau))
        return e, v

    rest, after = -0.5, -0.5 + force / 1e4
    y = np.empty_like(t)
    before = t < t_step
    y[before] = rest + free(t[before], 0.0 - rest, 0.0)[0]
    e1, v1 = free(t_step, 0.0 - rest, 0.0)
    y[~before] = after + free(t[~before] - t_step, rest + e1 - after, v1)[0]
    return y


def extrapolate(y_h: np.ndarray, y_h2: np.ndarray, y_h4: np.ndarray) -> np.ndarray:
    """Richardson extrapolation of runs at steps h, h/2, h/4 (sampled on the same instants) that
    removes the error terms in h and h²: (8·y(h/4) − 6·y(h/2) + y(h)) / 3."""
    return (8 * y_h4 - 6 * y_h2 + y_h) / 3


def run_keeping_instances(path: Path, **options) -> tuple[np.ndarray, dict[str, dict[str, int]], dict]:
    """Run like cosim.run.simulation.run but read each ME instance's event counts before it is freed."""
    prepared = prepare(path, **options)
    execution = Execution(prepared.plan, prepared.grid, prepared.algorithm)
    memory = MemorySink()
    try:
        execution.instantiate()
        names, arrays = execution.link(compile(prepared.plan, prepared.algorithm)).recorder_sources()
        recorder = Recorder(names, arrays, names, [memory])
        execution.initialize()
        execution.run(recorder)
        events = {name: inst.events for name, inst in execution.instances.items() if hasattr(inst, "events")}
        metadata = execution.metadata()
        recorder.close(metadata)
    finally:
        execution.close()
        prepared.close()
    return memory.array(), events, metadata


# --------------------------------------------------------------------------- (a) stiff plant, coarse step

def test_me_is_stable_at_10ms_where_the_cs_export_diverges(tmp_path, built_fmus, gemseo):
    me = cosim.simulate(force_step_system(tmp_path / "me", built_fmus, gemseo, "ModelExchange", stop=1.0, step=0.01))
    cs = cosim.simulate(force_step_system(tmp_path / "cs", built_fmus, gemseo, "CoSimulation", stop=1.0, step=0.01))
    # explicit Euler at h = 0.01: |1 + hλ| = |0.95 + 1.0i| ≈ 1.38 per step, so the CS run explodes
    assert np.abs(cs["plant.y"][-10:]).max() > 1e6
    assert np.abs(cs["plant.y"][50:]).max() > 100 * np.abs(cs["plant.y"][:50]).max()
    # ME: bounded by the undamped swing and settled near the new rest position −0.5 + 1000/1e4
    assert np.all(np.isfinite(me["plant.y"])) and np.abs(me["plant.y"]).max() < 1.0
    assert np.abs(me["plant.y"][me["time"] > 0.9] - (-0.4)).max() < 0.01


def test_me_at_10ms_agrees_with_fine_step_cs(tmp_path, built_fmus, gemseo):
    """ME at h = 0.01 against the CS export at 1e-4, 5e-5 and 2.5e-5 s over 0.3 s.  The CS error
    halves with h (Euler, first order: 0.022, 0.011, 0.0054 m measured) and the extrapolation
    that removes the h and h² terms agrees with ME to 1e-4 of the 0.92 m swing (measured 3.7e-5,
    the size of CVODE's own error at rtol 1e-6, see the analytic test below)."""
    me = cosim.simulate(force_step_system(tmp_path / "me", built_fmus, gemseo, "ModelExchange", stop=0.3,
                                          step=0.01))["plant.y"]
    steps = (1e-4, 5e-5, 2.5e-5)
    cs = {h: cosim.simulate(force_step_system(tmp_path / f"cs{h}", built_fmus, gemseo, "CoSimulation", stop=0.3,
                                              step=h))["plant.y"][::round(0.01 / h)] for h in steps}
    errors = [np.abs(cs[h] - me).max() for h in steps]
    assert 1.8 < errors[0] / errors[1] < 2.2 and 1.8 < errors[1] / errors[2] < 2.2
    assert np.abs(extrapolate(*cs.values()) - me).max() < 1e-4 * np.ptp(me)


def test_closed_loop_me_scenario_agrees_with_fine_step_cs(tmp_path, built_fmus, gemseo):
    """ssp/pid_mass_damper_me (PID sampled at 10 ms, Gauss-Seidel, controller first: u(t_k) = PID(y(t_k)))
    at its 10 ms step against the same loop with the plant's CS interface at 1e-4, 5e-5 and 2.5e-5 s
    over the first 0.3 s (the force saturates at ±2 kN): the extrapolation agrees to 2e-4 of the swing
    (measured 8e-5; first-order extrapolation alone leaves 1.3e-3, as the PID's derivative amplifies
    the CS error)."""
    me = cosim.simulate(ME_SCENARIO, fmu_dirs=[gemseo], stop_time=0.3)
    text = (ME_SCENARIO / "SystemStructure.ssd").read_text().replace('implementation="ModelExchange"',
                                                                      'implementation="CoSimulation"')
    folder = write_system(tmp_path / "cs", {}, text)
    shutil.copy(ME_SCENARIO / "controller.ssv", folder)
    cs = [cosim.simulate(folder, fmu_dirs=[gemseo], stop_time=0.3, step_size=h)["plant.y"][::round(0.01 / h)]
          for h in (1e-4, 5e-5, 2.5e-5)]
    swing = np.ptp(me["plant.y"])
    assert swing > 0.4  # the loop pulls the mass from 0 to −0.5 m
    assert np.abs(extrapolate(*cs) - me["plant.y"]).max() < 2e-4 * swing
    # and the scenario itself: settled on the set-point before its step, on the new one at the end
    full = cosim.simulate(ME_SCENARIO, fmu_dirs=[gemseo])
    t, y, r = full["time"], full["plant.y"], full["setpoint.y"]
    assert np.abs(y[(t > 1.2) & (t < 1.5)] + 0.5).max() < 0.002
    assert np.abs(y[t > 2.5] - r[t > 2.5]).max() < 0.001


# --------------------------------------------------------------------------- (c) analytic response

def test_me_equals_the_analytic_response_to_the_solver_tolerance(tmp_path, built_fmus, gemseo):
    """Default rtol (the FMU's DefaultExperiment tolerance 1e-6): error < 1e-4 m on a 0.92 m swing;
    rtol = 1e-9 from the org.greyfmu.solver annotation: 100 times smaller, so the difference is the
    solver's error and not a modelling mismatch."""
    errors = {}
    for rtol in (None, 1e-9):
        path = force_step_system(tmp_path / f"r{rtol}", built_fmus, gemseo, "ModelExchange", stop=1.0, step=0.01,
                                 solver=None if rtol is None else f'rtol="{rtol}"')
        result, events, metadata = run_keeping_instances(path)
        assert metadata["components"]["plant"]["solver"]["rtol"] == (rtol or 1e-6)
        assert events["plant"] == {"input": 1, "time": 0, "state": 0, "step": 0}  # the force step at 0.1 s
        errors[rtol] = np.abs(result["plant.y"] - mass_damper_analytic(result["time"], 0.1, 1000.0)).max()
    assert errors[None] < 1e-4
    assert errors[1e-9] < errors[None] / 100


# --------------------------------------------------------------------------- (b) events

def test_ramp_kinks_are_state_events_and_the_output_is_exact(tmp_path, gemseo):
    """ramp.fmu has no states and 2 event indicators (time − startTime, time − startTime − duration).
    OpenModelica evaluates its relations only at events, so without event handling the samples after
    the kinks (t = 0.3 and 0.8) would keep the old branch."""
    text = ssd_text("ramp", {"ramp": ("ramp.fmu", {"out": "output"})}, [], stop=1.0, step=0.1,
                    parameters={"ramp": {"ramp.startTime": 0.25, "ramp.duration": 0.5, "ramp.height": 2.0,
                                         "ramp.offset": 0.1}})
    path = write_system(tmp_path / "ramp", {"ramp.fmu": gemseo / "ramp.fmu"},
                        with_implementation(text, "ramp", "ModelExchange"))
    result, events, _ = run_keeping_instances(path)
    t = result["time"]
    np.testing.assert_allclose(result["ramp.out"], 0.1 + 2.0 * np.clip((t - 0.25) / 0.5, 0.0, 1.0),
                               rtol=0, atol=1e-9)
    assert events["ramp"]["state"] == 2
    assert events["ramp"]["time"] == events["ramp"]["step"] == 0


def test_mass_spring_system_me_agrees_with_fine_step_cs(tmp_path, gemseo):
    """Four states over 2 s: ME at h = 0.1 against the extrapolated CS runs at 2e-3, 1e-3, 5e-4 s,
    to 3e-5 of each signal's range (measured ≈ 1e-5: CVODE's own error at rtol 1e-6)."""
    comps = {"sys": ("MassSpringSystem.fmu", {"x1": "output", "x2": "output", "v1": "output", "v2": "output"})}
    runs = {}
    for impl, h in (("ModelExchange", 0.1), ("CoSimulation", 2e-3), ("CoSimulation", 1e-3), ("CoSimulation", 5e-4)):
        text = with_implementation(ssd_text("ms", comps, [], stop=2.0, step=h), "sys", impl)
        runs[h] = cosim.simulate(write_system(tmp_path / f"{impl}{h}", {"MassSpringSystem.fmu":
                                                                         gemseo / "MassSpringSystem.fmu"}, text))
    for name in ("sys.x1", "sys.x2", "sys.v1", "sys.v2"):
        me = runs[0.1][name]
        cs = [runs[h][name][::round(0.1 / h)] for h in (2e-3, 1e-3, 5e-4)]
        assert np.abs(extrapolate(*cs) - me).max() < 3e-5 * np.ptp(me)


# --------------------------------------------------------------------------- (d) SSD implementation, refusals

def test_implementation_model_exchange_on_a_cs_only_fmu_is_refused(tmp_path, built_fmus):
    text = with_implementation(ssd_text("s", {"src": ("Step.fmu", {"y": "output"})}, []), "src", "ModelExchange")
    path = write_system(tmp_path / "s", {"Step.fmu": built_fmus["Step"]}, text)
    with pytest.raises(cosim.SetupError) as err:
        prepare(path)
    message = str(err.value)
    assert "SystemStructure.ssd" in message and "ssd:Component 'src'" in message
    assert "implementation='ModelExchange' but Step.fmu has no Model Exchange interface" in message


def test_unknown_implementation_is_caught_by_the_ssp_schema(tmp_path, built_fmus):
    text = with_implementation(ssd_text("s", {"src": ("Step.fmu", {"y": "output"})}, []), "src", "Hybrid")
    path = write_system(tmp_path / "s", {"Step.fmu": built_fmus["Step"]}, text)
    with pytest.raises(cosim.SetupError) as err:
        prepare(path)
    assert "SSP 1.0 schema" in str(err.value) and "implementation" in str(err.value) and "Hybrid" in str(err.value)


def without_cosimulation(text: str) -> str:
    """Remove the CoSimulation element: an FMU exported for Model Exchange only."""
    start = text.index("<CoSimulation")
    close = text.find("</CoSimulation>", start)
    end = close + len("</CoSimulation>") if close >= 0 else text.index("/>", start) + 2
    return text[:start] + text[end:]


def test_an_me_only_fmu_runs_through_me_and_refuses_cosimulation(tmp_path, built_fmus, gemseo):
    me_only = edited_copy(gemseo / "Mass_Damper.fmu", tmp_path / "Mass_Damper.fmu", without_cosimulation)
    text = ssd_text("force_step", {"force": ("Step.fmu", {"y": "output"}),
                                   "plant": ("Mass_Damper.fmu", {"f": "input", "y": "output"})},
                    [("force", "y", "plant", "f")], stop=0.3, step=0.01,
                    parameters={"force": {"t_step": 0.1, "initial": 0.0, "final": 1000.0}})
    fmus = {"Step.fmu": built_fmus["Step"], "Mass_Damper.fmu": me_only}
    result, _, metadata = run_keeping_instances(write_system(tmp_path / "any", fmus, text))  # implementation="any"
    assert metadata["components"]["plant"]["interface"] == "fmi2-me"
    explicit = cosim.simulate(force_step_system(tmp_path / "me", built_fmus, gemseo, "ModelExchange", stop=0.3,
                                                step=0.01))
    np.testing.assert_array_equal(result["plant.y"], explicit["plant.y"])
    refused = write_system(tmp_path / "cs", fmus, with_implementation(text, "plant", "CoSimulation"))
    with pytest.raises(cosim.SetupError) as err:
        prepare(refused)
    assert "implementation='CoSimulation' but Mass_Damper.fmu has no Co-Simulation interface" in str(err.value)


def test_discrete_inputs_of_an_me_component_are_refused_before_running(tmp_path, built_fmus, gemseo):
    """FMI 2.0 §3.2.3 lets a discrete-time input be set only in Event Mode; the master sets inputs in
    Continuous-Time Mode, so `cosim validate` refuses it (the FMU's description declares f discrete)."""
    fmu = edited_copy(gemseo / "Mass_Damper.fmu", tmp_path / "Mass_Damper.fmu",
                      lambda text: text.replace('name="f"\n    valueReference="10"\n    causality="input"',
                                                'name="f"\n    valueReference="10"\n    causality="input"\n'
                                                '    variability="discrete"', 1))
    text = with_implementation(ssd_text("p", {"plant": ("Mass_Damper.fmu", {"f": "input", "y": "output"})}, []),
                               "plant", "ModelExchange")
    path = write_system(tmp_path / "s", {"Mass_Damper.fmu": fmu}, text)
    with pytest.raises(cosim.SetupError) as err:
        prepare(path)
    message = str(err.value)
    assert "ssd:Component 'plant'" in message and "variable 'f'" in message
    assert "discrete-time inputs (f)" in message and "Event Mode" in message


def test_solver_annotation_on_a_cs_component_or_with_unknown_attributes_is_refused(tmp_path, built_fmus, gemseo):
    text = ssd_text("s", {"src": ("Step.fmu", {"y": "output"})}, [])
    path = write_system(tmp_path / "cs", {"Step.fmu": built_fmus["Step"]}, with_solver(text, "src", 'rtol="1e-8"'))
    with pytest.raises(cosim.SetupError) as err:
        prepare(path)
    assert "org.greyfmu.solver" in str(err.value) and "Model Exchange components only" in str(err.value)
    bad = force_step_system(tmp_path / "bad", built_fmus, gemseo, "ModelExchange", stop=0.1, step=0.01,
                            solver='rtol="1e-8" method="RK45"')
    with pytest.raises(cosim.SetupError) as err:
        prepare(bad)
    assert "unknown attribute(s) method of greyfmu:Solver" in str(err.value)


def test_a_solver_failure_ends_the_run_with_the_solvers_message(tmp_path, built_fmus, gemseo):
    """maxStep = 1e-9 s needs 1e7 internal steps per 10 ms; CVODE gives up after 500 (fmpy's
    mxstep): do_step returns Error and the RunError carries CVODE's explanation."""
    path = force_step_system(tmp_path / "f", built_fmus, gemseo, "ModelExchange", stop=0.1, step=0.01,
                             solver='maxStep="1e-9"')
    with pytest.raises(cosim.RunError) as err:
        cosim.simulate(path)
    message = str(err.value)
    assert "component 'plant'" in message and "fmi2DoStep returned Error at t = 0" in message
    assert "CVode error" in message and "mxstep" in message.lower()


def test_info_shows_the_interface_and_the_solver(gemseo, capsys):
    from cosim.cli import main
    assert main(["info", str(ME_SCENARIO), "--fmu-dir", str(gemseo)]) == 0
    out = capsys.readouterr().out
    assert ('interface fmi2-me (implementation="ModelExchange"), integrated by the master: CVode (BDF), '
            'rtol 1e-06, max step communication step') in out
    assert 'interface fmi2-cs (implementation="any")' in out


def test_pack_keeps_the_implementation(tmp_path, gemseo):
    from cosim.cli import main
    archive = tmp_path / "me.ssp"
    assert main(["pack", str(ME_SCENARIO), "--fmu-dir", str(gemseo), "-o", str(archive)]) == 0
    with zipfile.ZipFile(archive) as z:
        assert 'implementation="ModelExchange"' in z.read("SystemStructure.ssd").decode()
    np.testing.assert_array_equal(cosim.simulate(archive, stop_time=0.5)["plant.y"],
                                  cosim.simulate(ME_SCENARIO, fmu_dirs=[gemseo], stop_time=0.5)["plant.y"])
