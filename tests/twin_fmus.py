"""C twins of our Step, Gain, Sum and FirstOrderFilter FMUs (fmus/Step.py, fmus/Gain.py,
fmus/Sum.py, fmus/FirstOrderFilter.py) for the master's tests
(tests/cfmus.py): the same variables, value references, descriptions, causalities, start values
and units, so a system written for ours runs on these without pythonfmu.

Step: y = initial before t_step, final from t_step on, at the FMU's current time (after
initialisation y(t0), after do_step(t, h) y(t + h)).  Gain: y = k * u; Sum: y = k1 u1 + k2 u2 +
k3 u3 (both direct feedthrough).
FirstOrderFilter: T dy/dt + y = K u integrated exactly with u held over the step,
y(t + h) = K u + (y(t) - K u) exp(-h / T), y(t0) = y0 (greyfmu.signals.FirstOrderFilter).
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

SUM = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Sum" guid="{5e0c0000-0000-4000-8000-0000000000a4}">
  <CoSimulation modelIdentifier="Sum" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0.0" stopTime="100.0" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="k1" valueReference="0" description="Weight of u1" causality="parameter"
      variability="fixed"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="k2" valueReference="1" description="Weight of u2" causality="parameter"
      variability="fixed"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="k3" valueReference="2" description="Weight of u3" causality="parameter"
      variability="fixed"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="u1" valueReference="3" description="First input" causality="input"
      variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="u2" valueReference="4" description="Second input" causality="input"
      variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="u3" valueReference="5" description="Third input" causality="input"
      variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="6" description="Weighted sum of the inputs" causality="output"
      variability="continuous" initial="exact"><Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="7" dependencies="4 5 6"/></Outputs></ModelStructure>
</fmiModelDescription>
"""
SUM_BODY = """
static void start(S *s) { s->r[0] = 1; s->r[1] = 1; s->r[2] = 1; }
static void calculate(S *s) { s->r[6] = s->r[0] * s->r[3] + s->r[1] * s->r[4] + s->r[2] * s->r[5]; }
static int step(S *s, double t, double h) { return 0; }
"""

FILTER = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="FirstOrderFilter" guid="{5e0c0000-0000-4000-8000-0000000000a3}">
  <CoSimulation modelIdentifier="FirstOrderFilter" canHandleVariableCommunicationStepSize="true"/>
  <UnitDefinitions><Unit name="s"><BaseUnit s="1"/></Unit></UnitDefinitions>
  <DefaultExperiment startTime="0.0" stopTime="100.0" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="K" valueReference="0" description="Static gain" causality="parameter" variability="fixed">
      <Real start="1"/></ScalarVariable>
    <ScalarVariable name="T" valueReference="1" description="Time constant (&gt; 0)" causality="parameter"
      variability="fixed"><Real start="1" unit="s"/></ScalarVariable>
    <ScalarVariable name="y0" valueReference="2" description="Initial output" causality="parameter" variability="fixed">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="3" description="Filter input" causality="input" variability="continuous">
      <Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="4" description="Filtered output" causality="output"
      variability="continuous" initial="exact"><Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="5" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""
#: s->b[60]: started (y = y0 until the first step, whatever y0 was set to after instantiation)
FILTER_BODY = """
#include <math.h>
static void start(S *s) { s->r[0] = 1; s->r[1] = 1; }
static void calculate(S *s) { if (!s->b[60]) s->r[4] = s->r[2]; }
static int step(S *s, double t, double h) {
    calculate(s); s->b[60] = 1;
    double target = s->r[0] * s->r[3];
    s->r[4] = target + (s->r[4] - target) * exp(-h / s->r[1]); return 0; }
"""


def build_twins(dest: Path) -> dict[str, Path]:
    """``dest/Step.fmu``, ``Gain.fmu``, ``Sum.fmu`` and ``FirstOrderFilter.fmu``, by file name."""
    return {"Step.fmu": build_c_fmu(dest, "Step", STEP, STEP_BODY), "Gain.fmu": build_c_fmu(dest, "Gain", GAIN, GAIN_BODY),
            "Sum.fmu": build_c_fmu(dest, "Sum", SUM, SUM_BODY),
            "FirstOrderFilter.fmu": build_c_fmu(dest, "FirstOrderFilter", FILTER, FILTER_BODY)}
