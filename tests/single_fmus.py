"""The C FMU of the single-FMU and input-table tests (tests/cfmus.py): inputs of every kind
(continuous Real u, discrete Real d, Integer k, Boolean b), an integrating state, a direct
feedthrough output and outputs that echo the discrete inputs, and a parameter."""
from __future__ import annotations

from pathlib import Path

from cfmus import build_c_fmu

#: (name, vr, causality, variability, type, start)
VARIABLES = [("u", 0, "input", "continuous", "Real", "0"), ("d", 1, "input", "discrete", "Real", "0"),
             ("k", 0, "input", "discrete", "Integer", "0"), ("b", 0, "input", "discrete", "Boolean", "false"),
             ("x", 2, "output", "continuous", "Real", None), ("y", 3, "output", "continuous", "Real", None),
             ("yk", 1, "output", "discrete", "Integer", None), ("yb", 1, "output", "discrete", "Boolean", None),
             ("yd", 4, "output", "discrete", "Real", None), ("gain", 5, "parameter", "fixed", "Real", "2")]


def description(guid: str = "{5f1e0c3a-3030-4000-8000-000000000030}", variable_step: bool = True,
                experiment: bool = True) -> str:
    rows, outputs = [], []
    for i, (name, vr, causality, variability, kind, start) in enumerate(VARIABLES, 1):
        initial = ' initial="exact"' if causality == "parameter" else ""
        attr = f' start="{start}"' if start is not None else ""
        rows.append(f'<ScalarVariable name="{name}" valueReference="{vr}" causality="{causality}" '
                    f'variability="{variability}"{initial}><{kind}{attr}/></ScalarVariable>')
        if causality == "output":
            outputs.append(f'<Unknown index="{i}" dependencies="{"1" if name == "y" else ""}"/>')
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="Drive" guid="{guid}" numberOfEventIndicators="0">'
            '<CoSimulation modelIdentifier="Drive" '
            f'canHandleVariableCommunicationStepSize="{str(variable_step).lower()}"/>'
            + ('<DefaultExperiment startTime="0" stopTime="2" stepSize="0.1"/>' if experiment else '')
            + f'<ModelVariables>{"".join(rows)}</ModelVariables>'
            f'<ModelStructure><Outputs>{"".join(outputs)}</Outputs></ModelStructure></fmiModelDescription>\n')


#: x integrates u (explicit Euler over the communication step) plus the discrete inputs' effect;
#: y = gain * u (direct feedthrough); yk, yb, yd echo k, b, d
BODY = r"""
static void start(S *s) { s->r[5] = 2.0; }
static void calculate(S *s) { s->r[3] = s->r[5] * s->r[0]; s->i[1] = s->i[0]; s->b[1] = s->b[0]; s->r[4] = s->r[1]; }
static int step(S *s, double t, double h) {
    s->r[2] += h * (s->r[0] + s->r[1] + s->i[0] + (s->b[0] ? 10.0 : 0.0)); return 0; }
"""


def build_drive(dest: Path, variable_step: bool = True, experiment: bool = True) -> Path:
    """``dest/Drive.fmu``; ``variable_step``: its canHandleVariableCommunicationStepSize (with it
    fmpy adds a communication point at every input event between two of the grid's); ``experiment``:
    a DefaultExperiment (0..2 s, step 0.1 s) or none."""
    return build_c_fmu(dest, "Drive", description(variable_step=variable_step, experiment=experiment), BODY)
