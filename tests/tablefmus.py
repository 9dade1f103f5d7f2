"""A small FMI 2.0 Co-Simulation FMU with Integer, Boolean and Enumeration parameters, outputs and
inputs, compiled at test time (`cfmus.build_c_fmu`), for the SSP 1.0 mapping transformations
(SystemStructureCommon.xsd, GTransformationChoice: Boolean, Integer and Enumeration mapping
tables) on parameters and on connections.

``Tables``, after k steps:

* parameters ``count`` (Integer), ``on`` (Boolean), ``level`` (Enumeration ``Level``: low 1,
  mid 2, high 3), reported unchanged by the outputs ``count_out``, ``on_out``, ``level_out``;
* outputs ``n = count + k`` (Integer), ``flag = on xor (k odd)`` (Boolean) and
  ``mode = (level - 1 + k) mod 3 + 1`` (Enumeration), so a value changes at every step;
* inputs ``n_in``, ``flag_in``, ``mode_in`` echoed by the direct-feedthrough outputs ``n_echo``,
  ``flag_echo``, ``mode_echo``.
"""
from __future__ import annotations

from pathlib import Path

from cfmus import build_c_fmu

LEVELS = {"low": 1, "mid": 2, "high": 3}

#: (name, value reference, FMI 2.0 type, causality)
VARIABLES = [("count", 0, "Integer", "parameter"), ("on", 1, "Boolean", "parameter"),
             ("level", 2, "Enumeration", "parameter"),
             ("count_out", 3, "Integer", "output"), ("on_out", 4, "Boolean", "output"),
             ("level_out", 5, "Enumeration", "output"),
             ("n", 6, "Integer", "output"), ("flag", 7, "Boolean", "output"), ("mode", 8, "Enumeration", "output"),
             ("n_in", 9, "Integer", "input"), ("flag_in", 10, "Boolean", "input"),
             ("mode_in", 11, "Enumeration", "input"),
             ("n_echo", 12, "Integer", "output"), ("flag_echo", 13, "Boolean", "output"),
             ("mode_echo", 14, "Enumeration", "output")]
STARTS = {"count": 1, "on": "false", "level": 1, "n_in": 0, "flag_in": "false", "mode_in": 1}
ECHOES = {"n_echo": "n_in", "flag_echo": "flag_in", "mode_echo": "mode_in"}

BODY = """
static void start(S *s) { s->i[0] = 1; s->b[1] = 0; s->i[2] = 1; s->i[9] = 0; s->b[10] = 0; s->i[11] = 1; }
static void calculate(S *s) {
    int k = s->i[63];
    s->i[3] = s->i[0]; s->b[4] = s->b[1]; s->i[5] = s->i[2];
    s->i[6] = s->i[0] + k; s->b[7] = s->b[1] ^ (k & 1); s->i[8] = (s->i[2] - 1 + k) % 3 + 1;
    s->i[12] = s->i[9]; s->b[13] = s->b[10]; s->i[14] = s->i[11]; }
static int step(S *s, double t, double h) { s->i[63] += 1; return 0; }
"""


def _description() -> str:
    index = {name: i for i, (name, *_) in enumerate(VARIABLES, 1)}
    rows, outputs = [], []
    for name, vr, kind, causality in VARIABLES:
        attrs = {"parameter": 'variability="fixed" initial="exact"', "input": 'variability="discrete"',
                 "output": 'variability="discrete"'}[causality]
        start = f' start="{STARTS[name]}"' if name in STARTS else ""
        declared = ' declaredType="Level"' if kind == "Enumeration" else ""
        rows.append(f'<ScalarVariable name="{name}" valueReference="{vr}" causality="{causality}" {attrs}>'
                    f'<{kind}{declared}{start}/></ScalarVariable>')
        if causality == "output":
            deps = str(index[ECHOES[name]]) if name in ECHOES else ""
            outputs.append(f'<Unknown index="{index[name]}" dependencies="{deps}"/>')
    items = "".join(f'<Item name="{n}" value="{v}"/>' for n, v in LEVELS.items())
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<fmiModelDescription fmiVersion="2.0" modelName="Tables" '
            'guid="{9e0c0000-0000-4000-8000-0000000000a1}" numberOfEventIndicators="0">'
            '<CoSimulation modelIdentifier="Tables" canHandleVariableCommunicationStepSize="true"/>'
            f'<TypeDefinitions><SimpleType name="Level"><Enumeration>{items}</Enumeration></SimpleType>'
            f'</TypeDefinitions><ModelVariables>{"".join(rows)}</ModelVariables>'
            f'<ModelStructure><Outputs>{"".join(outputs)}</Outputs>'
            f'<InitialUnknowns>{"".join(outputs)}</InitialUnknowns></ModelStructure></fmiModelDescription>\n')


def build_tables_fmu(dest: Path) -> Path:
    """``dest/Tables.fmu``."""
    return build_c_fmu(dest, "Tables", _description(), BODY, "2.0")
