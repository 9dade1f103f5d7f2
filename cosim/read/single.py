"""One FMU read as a system, as ``fmpy simulate`` runs it: `fmu_structure` builds a one-component
system in memory from an FMU (`cosim run X.fmu`).

The component is named after the FMU's model identifier, every input and output is a connector,
the default experiment of its modelDescription.xml gives the start and stop time and the step;
what follows is the path of an SSD (`cosim.plan.prepare`), so results are named
``<model>.<variable>``; each output is also an output connector of the system named as the
variable, so it is recorded again under the name fmpy gives its column (``y`` besides
``Drive.y``), and a result compares with an fmpy result or a cross-check reference by name
(`cosim compare ref.csv result.csv`).  A missing step is fmpy's automatic interval
(`auto_interval`, fmpy's own function: the step ``fmpy simulate`` would take).
"""
from __future__ import annotations

from pathlib import Path

from fmpy.util import auto_interval

from ..errors import SetupError
from ..model.fmu import exchange_type, recorded_type
from ..model.structure import (
    Component,
    Connection,
    Connector,
    Experiment,
    RawStructure,
    RawSystem,
    ScenarioFiles,
    SystemStructure,
)
from .description import describe_fmu
from .flatten import flatten

__all__ = ["auto_interval", "fmu_structure", "is_fmu"]


def is_fmu(path: str | Path) -> bool:
    """Whether ``path`` names one FMU (an ``.fmu`` file, or a path that is not a folder)."""
    return Path(path).suffix.lower() == ".fmu" and not Path(path).is_dir()


def fmu_structure(path: str | Path, implementation: str = "any") -> SystemStructure:
    """A one-component system of the FMU at ``path``, flattened as an SSD's would be;
    ``implementation``: the SSP Component's choice of interface (``--fmi-type``)."""
    fmu = Path(path)
    if not fmu.is_file():
        raise SetupError("no such FMU file.", file=str(fmu), element="cosim run X.fmu")
    # checked as run loads it, named as given; its warnings come when the plan describes it
    desc = describe_fmu(fmu, "the FMU given", str(fmu), implementation, warn=False)
    name = desc.model_identifier
    # a numeric or Boolean array is one connector, made one per element by the plan (cosim.plan.arrays);
    # what is no connector (String and Binary arrays, Clocks) the plan names in a warning
    connectors = {v.name: Connector(v.name, v.causality, None, None, 0) for v in desc.variables.values()
                  if v.causality in ("input", "output") and exchange_type(v) is not None
                  and (not v.dimensions or recorded_type(v))}
    component = Component(name, fmu.name, 0, connectors, implementation=implementation)
    e = desc.default_experiment
    start = float(e.start_time) if e is not None and e.start_time is not None else None
    stop = float(e.stop_time) if e is not None and e.stop_time is not None else None
    step = float(e.step_size) if e is not None and e.step_size is not None else None
    outputs = [c for c in connectors.values() if c.kind == "output" and recorded_type(desc.variables[c.name])]
    aliases = {c.name: Connector(c.name, "output", None, None, 0) for c in outputs}
    wires = [Connection(name, c.name, None, c.name, None, False, 0) for c in outputs]
    root = RawSystem(name, 0, aliases, {name: component}, {}, wires, [], [name])
    raw = RawStructure(name=name, files=ScenarioFiles(fmu, fmu.parent, None), display=str(fmu), root=root,
                       experiment=Experiment(start, stop, step, "modelDescription.xml DefaultExperiment stepSize"
                                             if step is not None else None, None), units={})
    return flatten(raw)
