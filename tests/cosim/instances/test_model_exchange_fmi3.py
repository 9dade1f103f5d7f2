"""FMI 3.0 Model Exchange FMUs hosted by the master like FMI 2.0 ones (cosim.run.instances.me,
`ME3Instance`, on fmpy's FMU3Model and CVODE), with state events; issue 21, item 6.  The FMU is
a bouncing ball compiled here (tests/cfmus.py); references: fmpy.simulate_fmu on the same FMU
and the analytic first flight."""
from __future__ import annotations

import json
import math

import fmpy
import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from ssdgen import ssd_text, write_system

BALL3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Ball3" instantiationToken="{9e0c0000-0000-4000-8000-0000000000b3}">
  <ModelExchange modelIdentifier="Ball3"/>
  <DefaultExperiment startTime="0" stopTime="3" tolerance="1e-8"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="h" valueReference="0" causality="output" variability="continuous" initial="exact" start="1"/>
    <Float64 name="der(h)" valueReference="8" causality="local" variability="continuous" derivative="0"/>
    <Float64 name="v" valueReference="1" causality="output" variability="continuous" initial="exact" start="0"/>
    <Float64 name="der(v)" valueReference="9" causality="local" variability="continuous" derivative="1"/>
    <Float64 name="e" valueReference="5" causality="parameter" variability="fixed" start="0.7"/>
    <Float64 name="g" valueReference="6" causality="parameter" variability="fixed" start="9.81"/>
    <Float64 name="lift" valueReference="7" causality="input" variability="continuous" start="0"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="0" dependencies=""/><Output valueReference="1" dependencies=""/>
    <ContinuousStateDerivative valueReference="8"/><ContinuousStateDerivative valueReference="9"/>
    <EventIndicator valueReference="0"/>
  </ModelStructure>
</fmiModelDescription>
"""
#: h' = v, v' = lift − g; when h reaches 0 falling, v ← −e·v (a state event on the indicator h)
BALL3_BODY = """
#define NX 2
#define NZ 1
static void start(S *s) { s->r[0] = 1.0; s->r[1] = 0.0; s->r[5] = 0.7; s->r[6] = 9.81; }
static void calculate(S *s) { s->r[8] = s->r[1]; s->r[9] = s->r[7] - s->r[6]; }
static int step(S *s, double t, double h) { return 3; }
static void derivatives(S *s, double dx[]) { dx[0] = s->r[1]; dx[1] = s->r[7] - s->r[6]; }
static void indicators(S *s, double z[]) { z[0] = s->r[0]; }
static void event(S *s) { if (s->r[0] <= 0 && s->r[1] < 0) { s->r[0] = 0.0; s->r[1] = -s->r[5] * s->r[1]; } }
"""
STOP, H = 2.0, 0.01


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return build_c_fmu(tmp_path_factory.mktemp("ball3"), "Ball3", BALL3, BALL3_BODY, "3.0", model_exchange=True)


def test_fmi3_model_exchange_ball_bounces_like_fmpy(tmp_path, ball):
    comps = {"ball": ("Ball3.fmu", {"h": "output", "v": "output"})}
    folder = write_system(tmp_path / "s", {"Ball3.fmu": ball}, ssd_text("ball", comps, [], stop=STOP, step=H))
    out = tmp_path / "o.csv"
    ours = cosim.simulate(folder, output=out)
    meta = json.loads(out.with_suffix(".json").read_text())["components"]["ball"]
    assert meta["interface"] == "fmi3-me" and meta["solver"]["rtol"] == 1e-8
    ref = fmpy.simulate_fmu(str(ball), stop_time=STOP, output_interval=H, output=["h", "v"], relative_tolerance=1e-8)
    on_grid = np.isclose(ref["time"] / H, np.round(ref["time"] / H), rtol=0, atol=1e-9)
    ref = ref[on_grid]       # fmpy adds a row before and after each event
    assert len(ours) == len(ref) == 201
    np.testing.assert_allclose(ours["time"], ref["time"], rtol=0, atol=1e-12)
    t = ours["time"]
    falling = t < math.sqrt(2 / 9.81)
    np.testing.assert_allclose(ours["ball.h"][falling], 1 - 9.81 * t[falling] ** 2 / 2, rtol=0, atol=1e-6)
    rebound = 0.7 * math.sqrt(2 * 9.81)    # the speed after the first bounce, sampled within a step of it
    assert ours["ball.h"].min() > -1e-6 and rebound - 9.81 * H <= ours["ball.v"].max() <= rebound + 1e-6
    for name in ("h", "v"):  # both integrate with CVODE at rtol 1e-8: agree to the solver's error
        np.testing.assert_allclose(ours[f"ball.{name}"], ref[name], rtol=0, atol=1e-4, err_msg=name)
    assert np.sum(np.diff(np.sign(ours["ball.v"])) > 0) >= 3     # several bounces: state events handled


def test_fmi3_model_exchange_input_from_an_fmi2_fmu(tmp_path, ball, twin_fmus):
    """lift from the FMI 2.0 Step: 0 until t = 0.2, then 9.81 (the ball floats at the speed it had,
    −9.81·0.2, an input event at t = 0.2)."""
    comps = {"s": ("Step.fmu", {"y": "output"}), "ball": ("Ball3.fmu", {"lift": "input", "h": "output", "v": "output"})}
    text = ssd_text("ball", comps, [("s", "y", "ball", "lift")], stop=0.5, step=H,
                    parameters={"s": {"t_step": 0.2, "initial": 0.0, "final": 9.81}})
    res = cosim.simulate(write_system(tmp_path / "s", {"Ball3.fmu": ball, "Step.fmu": twin_fmus["Step"]}, text))
    after = res["time"] > 0.2 + 1e-9
    np.testing.assert_allclose(res["ball.v"][after], -9.81 * 0.2, rtol=0, atol=1e-6)
    np.testing.assert_allclose(res["ball.h"][after], 1 - 9.81 * 0.2 ** 2 / 2 - 9.81 * 0.2 * (res["time"][after] - 0.2),
                               rtol=0, atol=1e-6)
