"""How the master integrates the Model Exchange components it hosts (`cosim.run.instances.me`):
the solver settings of each, and what is checked before instantiation."""
from __future__ import annotations

from ..model.fmu import MODEL_EXCHANGE, FMUDescription
from ..errors import SetupError
from ..model.structure import SolverOptions, SolverSettings, SystemStructure

#: Relative tolerance when the FMU's DefaultExperiment gives none.
DEFAULT_RTOL = 1e-6


def solver_settings(desc: FMUDescription, options: SolverOptions | None = None) -> SolverSettings:
    """CVODE (BDF) at the component's ``org.greyfmu.solver`` rtol, else the FMU's
    DefaultExperiment tolerance, else 1e-6; absolute tolerances are rtol × the states' nominal
    values (as fmpy does).  The largest internal step is the annotation's maxStep (capped at the
    communication step), else the communication step."""
    experiment = desc.default_experiment
    tolerance = experiment.tolerance if experiment is not None and experiment.tolerance else None
    rtol = float(tolerance) if tolerance else DEFAULT_RTOL
    if options is not None and options.rtol is not None:
        rtol = options.rtol
    return SolverSettings(method="CVode (BDF)", rtol=rtol, max_step=options.max_step if options else None)


def solvers_of(structure: SystemStructure, fmus: dict[str, FMUDescription]) -> dict[str, SolverSettings]:
    """The solver settings of every component the master integrates (kinds ``fmi2-me``, ``fmi3-me``)."""
    return {name: solver_settings(desc, structure.components[name].solver)
            for name, desc in fmus.items() if desc.kind in MODEL_EXCHANGE}


def check_model_exchange(structure: SystemStructure, fmus: dict[str, FMUDescription]) -> None:
    """What can be checked before instantiation: an ``org.greyfmu.solver`` annotation only on a
    component the master integrates (a Co-Simulation FMU integrates itself: refused rather than
    ignored), and no discrete-time inputs on one, which FMI 2.0 (§3.2.3) and FMI 3.0 (§3.1) let an
    importer set only in Event Mode while this master sets inputs at communication points in
    Continuous-Time Mode."""
    file = structure.display
    for name, comp in structure.components.items():
        desc = fmus[name]
        if comp.solver is not None and desc.kind not in MODEL_EXCHANGE:
            raise SetupError(f"component '{name}' runs through its {desc.kind} interface, which integrates "
                             "itself; the solver annotation applies to Model Exchange components only.",
                             file=comp.solver.file, element=f"{comp.solver.element} of ssd:Component '{name}'",
                             hint='Add implementation="ModelExchange" to the component or remove the annotation.')
        if desc.kind not in MODEL_EXCHANGE:
            continue
        discrete = [v.name for v in desc.variables.values() if v.causality == "input" and v.variability != "continuous"]
        if discrete:
            raise SetupError(f"{desc.path.name} runs through its Model Exchange interface and has discrete-time "
                             f"inputs ({', '.join(discrete)}), which "
                             + ("FMI 2.0 lets an importer set only in Event Mode (§3.2.3)" if desc.kind == "fmi2-me"
                                else "FMI 3.0 lets an importer set only in Event Mode (§3.1, Model Exchange's "
                                     "state machine)")
                             + "; this master sets inputs at communication points in Continuous-Time Mode.",
                             file=file, element=f"ssd:Component '{name}' (line {comp.line})", variable=discrete[0],
                             hint='Use its Co-Simulation interface (implementation="CoSimulation") if it has one.')
