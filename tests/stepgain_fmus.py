"""C twins of our Step and Gain FMUs (fmus/Step.py, fmus/Gain.py) for the master's tests
(tests/cfmus.py): the same variables, value references, descriptions, causalities, start values
and units, so a system written for ours runs on these without pythonfmu.

Step: y = initial before t_step, final from t_step on, at the FMU's current time (after
initialisation y(t0), after do_step(t, h) y(t + h)).  Gain: y = k * u (direct feedthrough).
"""
from __future__ import annotations

from pathlib import Path

from cfmus import build_c_fmu

STEP = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Step" guid="{5e0c0000-0000-4000-8000-0000000000a1}">
  <CoSimulation modelIdentifier="Step" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions><Unit name="s"><BaseUnit s="1"/></Unit></UnitDefinitions>
  <DefaultExperiment startTime="0.0" stopTime="100.0" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="t_step" valueReference="0" description="Step time" causality="parameter" variability="fixed">
      <Real start="1" unit="s"/></ScalarVariable>
    <ScalarVariable name="initial" valueReference="1" description="Output before the step" causality="parameter" variability="fixed">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="final" valueReference="2" description="Output from the step time on" causality="parameter" variability="fixed">
      <Real start="1"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="3" description="Step output" causality="output" variability="discrete" initial="exact">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="4" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""
STEP_BODY = """
static void start(S *s) { s->r[0] = 1; s->r[1] = 0; s->r[2] = 1; }
static void calculate(S *s) { s->r[3] = s->time >= s->r[0] ? s->r[2] : s->r[1]; }
static int step(S *s, double t, double h) { return 0; }
"""

GAIN = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Gain" guid="{5e0c0000-0000-4000-8000-0000000000a2}">
  <CoSimulation modelIdentifier="Gain" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0.0" stopTime="100.0" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="k" valueReference="0" description="Gain" causality="parameter" variability="fixed">
      <Real start="1"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="1" description="Input" causality="input" variability="continuous">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="2" description="k times the input" causality="output" variability="continuous" initial="exact">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="3" dependencies="2"/></Outputs></ModelStructure>
</fmiModelDescription>
"""
GAIN_BODY = """
static void start(S *s) { s->r[0] = 1; }
static void calculate(S *s) { s->r[2] = s->r[0] * s->r[1]; }
static int step(S *s, double t, double h) { return 0; }
"""


def build_step_and_gain(dest: Path) -> dict[str, Path]:
    """``dest/Step.fmu`` and ``dest/Gain.fmu``, by file name."""
    return {"Step.fmu": build_c_fmu(dest, "Step", STEP, STEP_BODY), "Gain.fmu": build_c_fmu(dest, "Gain", GAIN, GAIN_BODY)}
