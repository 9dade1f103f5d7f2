"""The discrete-state iteration of Model Exchange FMUs (cosim.run.instances.me) is bounded and as
tolerant as fmpy's; issue 30, item 4.  The FMUs are compiled here (tests/cfmus.py) and bend
the standard on purpose:

* "lenient": fmi2NewDiscreteStates / fmi3UpdateDiscreteStates only ever *set* the
  new-discrete-states flag, never write false (an exporter's habit).  fmpy passes a fresh
  zeroed struct (FMI 3.0: fresh zeroed flags) on every call, so the iteration ends; the master
  used to reuse one struct initialised to true and looped for ever.
* "chatter": from t = 0.25 the flag is always true: the iteration cannot end, and the run
  fails with the component, the flag and t.

Both count time events every 0.1 s: x' = 1, n += 1 at each multiple of 0.1.
"""
from __future__ import annotations

import fmpy
import numpy as np
import pytest

import cosim
from cfmus import build_c_fmu
from cosim.run.instances.me import MAX_DISCRETE_ITERATIONS
from ssdgen import ssd_text, write_system

FMI2_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{{9e0c0000-0000-4000-8000-0000000000c2}}"
  numberOfEventIndicators="0">
  <ModelExchange modelIdentifier="{name}"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0" causality="output" variability="continuous" initial="exact">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="der(x)" valueReference="8" causality="local" variability="continuous">
      <Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="2" causality="output" variability="discrete" initial="exact">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1"/><Unknown index="3"/></Outputs>
    <Derivatives><Unknown index="2"/></Derivatives></ModelStructure>
</fmiModelDescription>
"""
FMI3_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{{9e0c0000-0000-4000-8000-0000000000c3}}">
  <ModelExchange modelIdentifier="{name}"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="x" valueReference="0" causality="output" variability="continuous" initial="exact" start="0"/>
    <Float64 name="der(x)" valueReference="8" causality="local" variability="continuous" derivative="0"/>
    <Float64 name="n" valueReference="2" causality="output" variability="discrete" initial="exact" start="0"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="0" dependencies=""/><Output valueReference="2" dependencies=""/>
    <ContinuousStateDerivative valueReference="8"/>
  </ModelStructure>
</fmiModelDescription>
"""
COMMON_BODY = """
#define NX 1
#define NZ 0
#define CUSTOM_UPDATE
static void start(S *s) { s->r[0] = 0.0; s->r[2] = 0.0; s->r[3] = 0.1; }
static void calculate(S *s) { s->r[8] = 1.0; }
static int step(S *s, double t, double h) { return 3; }
static void derivatives(S *s, double dx[]) { dx[0] = 1.0; }
static void indicators(S *s, double z[]) { }
static void event(S *s) { }
/* the time event: count it, schedule the next; 1 if it fired (the new-states flag) */
static int tick(S *s) {
    if (s->time < s->r[3] - 1e-9) return 0;
    s->r[2] += 1.0; s->r[3] += 0.1; return 1; }
static int needed(S *s, int fired) { return CHATTER ? fired || s->time >= 0.25 : fired; }
"""
#: writes the flag only when it is true, never false
FMI2_UPDATE = """
int fmi2NewDiscreteStates(void *c, EventInfo *info) {
    S *s = c; int fired = tick(s);
    if (needed(s, fired)) info->newDiscreteStatesNeeded = 1;
    info->terminateSimulation = 0; info->valuesOfContinuousStatesChanged = 0;
    info->nextEventTimeDefined = 1; info->nextEventTime = s->r[3]; return 0; }
"""
FMI3_UPDATE = """
int fmi3UpdateDiscreteStates(void *c, bool *needUpdate, bool *terminate, bool *nominalsChanged, bool *valuesChanged,
        bool *nextDefined, double *next) {
    S *s = c; int fired = tick(s);
    if (needed(s, fired)) *needUpdate = true;
    *terminate = false; *valuesChanged = false; *nextDefined = true; *next = s->r[3]; return 0; }
"""
STOP, H = 0.5, 0.05


def build(folder, fmi: str, chatter: bool):
    name = ("Chatter" if chatter else "Lenient") + fmi[0]
    description = (FMI2_DESCRIPTION if fmi == "2.0" else FMI3_DESCRIPTION).format(name=name)
    body = f"#define CHATTER {int(chatter)}\n" + COMMON_BODY + (FMI2_UPDATE if fmi == "2.0" else FMI3_UPDATE)
    return build_c_fmu(folder, name, description, body, fmi, model_exchange=True)


def system(folder, fmu):
    comps = {"tick": (fmu.name, {"x": "output", "n": "output"})}
    return write_system(folder / "s", {fmu.name: fmu}, ssd_text("tick", comps, [], stop=STOP, step=H))


@pytest.mark.parametrize("fmi", ["2.0", "3.0"])
def test_an_fmu_that_never_clears_the_flag_runs_as_under_fmpy(tmp_path, fmi):
    fmu = build(tmp_path, fmi, chatter=False)
    ours = cosim.simulate(system(tmp_path, fmu))
    ref = fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=H, output=["x", "n"])
    on_grid = np.isclose(ref["time"] / H, np.round(ref["time"] / H), rtol=0, atol=1e-9)
    ref = ref[on_grid]     # fmpy adds a row before and after each event; the last one per time
    _, last = np.unique(np.round(ref["time"] / H), return_index=True)
    ref = ref[np.concatenate([last[1:] - 1, [len(ref) - 1]])]
    assert len(ours) == len(ref) == 11
    np.testing.assert_allclose(ours["tick.x"], ours["time"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(ours["tick.n"], np.floor(ours["time"] / 0.1 + 1e-6))   # every tick counted once
    np.testing.assert_array_equal(ours["tick.n"], ref["n"])
    assert ours["tick.n"][-1] == 5


@pytest.mark.parametrize("fmi, function, flag", [("2.0", "fmi2NewDiscreteStates", "newDiscreteStatesNeeded"),
                                                 ("3.0", "fmi3UpdateDiscreteStates", "discreteStatesNeedUpdate")])
def test_a_discrete_iteration_that_never_ends_fails_naming_the_fmu_the_flag_and_t(tmp_path, fmi, function, flag):
    """The first Event Mode after t = 0.25 is the time event at t = 0.3."""
    with pytest.raises(cosim.RunError) as err:
        cosim.simulate(system(tmp_path, build(tmp_path, fmi, chatter=True)))
    message = str(err.value)
    assert f"component 'tick': {function} still sets {flag} after {MAX_DISCRETE_ITERATIONS} iterations" in message
    assert "at t = 0.3 " in message and err.value.time == pytest.approx(0.25)


#: terminateSimulation at the time event of t = 0.3 (a grid point: H = 0.05)
FMI2_TERMINATE = FMI2_UPDATE.replace("info->terminateSimulation = 0;", "info->terminateSimulation = s->time >= 0.3 - 1e-9;")
FMI3_TERMINATE = FMI3_UPDATE.replace("*terminate = false;", "*terminate = s->time >= 0.3 - 1e-9;")


@pytest.mark.parametrize("fmi", ["2.0", "3.0"])
def test_an_fmu_that_terminates_at_a_time_event_on_the_grid_ends_the_run_there_with_that_point(tmp_path, fmi):
    """A Model Exchange FMU asking to terminate in the Event Mode of a time event at a
    communication point ends the run there, that point recorded (as a Co-Simulation FMU's
    completed step is): the run ended at the last good time 0.25 before, and said 'fmi3DoStep
    returned Discard' of a Model Exchange FMU (the Reference FMUs' Stair)."""
    name = f"Stop{fmi[0]}"
    description = (FMI2_DESCRIPTION if fmi == "2.0" else FMI3_DESCRIPTION).format(name=name)
    body = "#define CHATTER 0\n" + COMMON_BODY + (FMI2_TERMINATE if fmi == "2.0" else FMI3_TERMINATE)
    fmu = build_c_fmu(tmp_path, name, description, body, fmi, model_exchange=True)
    ours = cosim.simulate(system(tmp_path, fmu))
    assert ours["time"][-1] == pytest.approx(0.3)
    np.testing.assert_allclose(ours["tick.x"], ours["time"], rtol=0, atol=1e-9)
