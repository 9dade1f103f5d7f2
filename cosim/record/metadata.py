"""What a run's metadata JSON says of its signals, from the plan alone: each recorded connector's
description, the connections and their transformations, the sampled outputs, the parameters'
descriptions and units (`signal_info`); `cosim.run.simulation` writes it with the rest of the run's
metadata, and `cosim.present.plots` and `cosim.present.report` label a result from it."""
from __future__ import annotations

from ..model.fmu import unit_of
from ..model.structure import Plan


def signal_info(plan: Plan) -> dict:
    """What a plot or report needs to label a result: each recorded connector's description
    (from its FMU), the connections (``src.var -> dst.var``) and the transformation of each that
    has one (`cosim.model.transforms.Transform.text`, of the source's name)."""
    variables = {f"{c}.{v.name}": v for c in plan.outputs for v in plan.outputs[c] + plan.inputs[c]}
    return {"descriptions": {n: v.description for n, v in variables.items() if v.description},
            "connections": [r.label for r in plan.routes],
            "transforms": {r.label: r.transform.text(r.source) for r in plan.routes if not r.transform.identity},
            # sampled outputs (FMI variability discrete): held between samples, drawn as steps
            "discrete": sorted(n for n, v in variables.items() if v.variability == "discrete"),
            "parameter_descriptions": {f"{sv.component}.{sv.variable.name}": sv.variable.description
                                       for sv in plan.start_values if sv.variable.description},
            "parameter_units": {f"{sv.component}.{sv.variable.name}": unit_of(sv.variable)
                                for sv in plan.start_values if unit_of(sv.variable)}}
