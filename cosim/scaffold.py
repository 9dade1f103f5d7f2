"""``cosim new``: a scenario folder that closes a loop of a controller FMU around a plant FMU.

Given a plant FMU (any tool's) and a controller (an FMU file, or a name an FMU provider makes:
``PID``, ``GrayPredictivePI``, ...), `new_scenario` writes

- ``SystemStructure.ssd``: a set-point Step, the controller and the plant, wired by the
  controller's ``org.greyfmu`` annotation (`cosim.read.annotations`): its set-point input from
  the Step, its measurement input from a plant output, its manipulated output into a plant
  input; the plant through its Model Exchange interface where it has one (the master integrates it
  under error control, `_plant_description`).  Ports are matched by causality and type (Real), and by unit where the controller's
  port declares one (a measurement in MPa takes a plant output in a unit of pressure); among
  several candidates the first in the model description is taken, or the one named with
  ``--plant-input``/``--plant-output``.  Each connector carries the plant port's unit, so plots
  read in engineering units.  The grid: the plant's DefaultExperiment stop time (else 10 s)
  and a step that divides the controller's sample time;
- ``controller.ssv``: every controller parameter at its default, with unit and description in
  a comment: what to tune;
- ``resources/<plant>.fmu``: a copy of the plant;
- ``README.md``: the wiring and what is left to wire (other controller inputs its law reads,
  plant inputs left at their start values), and the commands to run it.

It returns what it wrote and the list of things left, which ``cosim new`` prints.
"""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from .errors import SetupError, did_you_mean
from .model.fmu import FMUDescription, Variable, unit_of
from .model.units import BUILTIN, fmu_units
from .read.annotations import LoopAnnotation, LoopPort, loop_annotation
from .read.description import describe
from .read.resources import providers

SETPOINT_FMU = "Step.fmu"


@dataclass(frozen=True)
class NewScenario:
    folder: Path
    files: tuple[Path, ...]
    wiring: tuple[str, ...]
    left: tuple[str, ...]


def _controller_fmu(controller: str) -> Path:
    """An FMU file, or the FMU a provider makes for a name (``PID`` -> ``PID.fmu``)."""
    path = Path(controller)
    if path.suffix.lower() == ".fmu" and path.is_file():
        return path
    name = path.name if path.suffix.lower() == ".fmu" else f"{controller}.fmu"
    loaded, _ = providers()
    for provide in loaded:
        found = provide(name)
        if found is not None:
            return Path(found)
    raise SetupError(f"no controller FMU '{controller}': not a file, and no FMU provider makes {name}.",
                     element="--controller", hint="`greyfmu info` lists our controllers; or give an .fmu file.")


def _real(desc: FMUDescription, causality: str) -> list[Variable]:
    return [v for v in desc.variables.values() if v.causality == causality and v.type in ("Real", "Float64")
            and not v.dimensions]


def _dimension(unit: str | None, known: dict):
    found = known.get(unit) if unit else None
    return None if found is None else found.exponents


def _pick(candidates: list[Variable], wanted: str | None, option: str, unit: str | None, known: dict) -> Variable:
    """The named candidate, else the first whose unit has the dimension of ``unit`` (when given), else the first."""
    if wanted is not None:
        found = next((v for v in candidates if v.name == wanted), None)
        if found is None:
            raise SetupError(f"the plant has no Real port '{wanted}' of that causality.", element=option,
                             variable=wanted, hint=did_you_mean(wanted, [v.name for v in candidates]))
        return found
    if _dimension(unit, known) is not None:
        same = [v for v in candidates if _dimension(unit_of(v), known) == _dimension(unit, known)]
        if same:
            return same[0]
    return candidates[0]


def _connector(name: str, kind: str, unit: str | None) -> str:
    real = f"<ssc:Real unit={quoteattr(unit)}/>" if unit else "<ssc:Real/>"
    return f'          <ssd:Connector name={quoteattr(name)} kind="{kind}">{real}</ssd:Connector>'


def _role(facts: LoopAnnotation | None, role: str, causality: str, fallback: str) -> list[LoopPort]:
    """The controller's ports of ``role`` (its annotation), else the one named ``fallback`` (r, y, u)."""
    if facts is not None:
        return [p for p in facts.ports if p.role == role and p.causality == causality]
    return [LoopPort(fallback, causality, role)]


def _number(text: str | None, default: float) -> float:
    try:
        return float(text) if text is not None else default
    except ValueError:
        return default


def _plant_description(plant: Path, interface: str | None) -> FMUDescription:
    """The plant through ``interface`` (CoSimulation or ModelExchange), else its Model Exchange
    interface where it has one: the master integrates it with CVODE under error control, so the
    loop does not hinge on the communication step (a Co-Simulation export may integrate with
    explicit Euler at the step: OpenModelica's Mass_Damper diverges above 5e-4 s), else its
    Co-Simulation interface."""
    if interface is not None:
        return describe(plant, "--plant-interface", str(plant), interface)
    try:
        return describe(plant, "--plant", str(plant), "ModelExchange")
    except SetupError:
        return describe(plant, "--plant", str(plant), "CoSimulation")


def new_scenario(folder: str | Path, plant: str | Path, controller: str = "PID", *, plant_input: str | None = None,
                 plant_output: str | None = None, plant_interface: str | None = None, setpoint: float | None = None,
                 step: float | None = None, stop: float | None = None, force: bool = False) -> NewScenario:
    """Write the scenario of the module docstring into ``folder`` (refused if it holds a
    SystemStructure.ssd, unless ``force``)."""
    folder = Path(folder)
    plant = Path(plant)
    if not plant.is_file():
        raise SetupError("no such plant FMU file.", file=str(plant), element="--plant")
    if (folder / "SystemStructure.ssd").exists() and not force:
        raise SetupError(f"{folder} already holds a SystemStructure.ssd; choose another folder or pass --force.",
                         element="cosim new")
    plant_desc = _plant_description(plant, plant_interface)
    controller_path = _controller_fmu(controller)
    control = describe(controller_path, "--controller", str(controller_path))
    facts = loop_annotation(controller_path)
    setpoints = _role(facts, "setpoint", "input", "r")
    measurements = _role(facts, "measurement", "input", "y")
    manipulated = _role(facts, "manipulated", "output", "u")
    if facts is None and not {"r", "y", "u"} <= set(control.variables):
        raise SetupError(f"{controller_path.name} carries no org.greyfmu annotation and has no ports r, y, u: "
                         "cosim new cannot tell its set-point, measurement and output.", element="--controller")
    if not (setpoints and measurements and manipulated):
        raise SetupError(f"{controller_path.name} is not a controller: its org.greyfmu annotation names no set-point "
                         "input, measurement input and manipulated output.", element="--controller",
                         hint="`greyfmu info` lists the controllers.")
    inputs, outputs = _real(plant_desc, "input"), _real(plant_desc, "output")
    if not inputs or not outputs:
        raise SetupError(f"{plant.name} needs a Real input and a Real output to close a loop around "
                         f"(it has {len(inputs)} and {len(outputs)}).", file=str(plant), element="--plant")
    measurement_var = control.variables[measurements[0].name]
    u_var = control.variables[manipulated[0].name]
    known = {**BUILTIN, **fmu_units(control.unit_definitions, control.path.name),
             **fmu_units(plant_desc.unit_definitions, plant.name)}
    measured = _pick(outputs, plant_output, "--plant-output", unit_of(measurement_var), known)
    driven = _pick(inputs, plant_input, "--plant-input", unit_of(u_var), known)
    y_unit, u_unit = unit_of(measured), unit_of(driven)

    ts_name = facts.sample_time if facts is not None else None
    ts = _number(control.variables[ts_name].start, 0.0) if ts_name in control.variables else None
    e = plant_desc.default_experiment
    stop = stop if stop is not None else _number(e.stop_time if e else None, 10.0)
    if step is None:
        plant_step = _number(e.step_size if e else None, 0.0)
        step = ts if ts else (plant_step or stop / 1000)
        if ts and 0 < plant_step < ts:
            step = ts / round(ts / plant_step + 0.4999999)   # the largest divisor of Ts not above the plant's step
    y0 = _number(measured.start, 0.0)
    final = setpoint if setpoint is not None else y0 + 1.0

    ctrl_name, plant_name = controller_path.name, plant.name
    controller_connectors = [_connector(setpoints[0].name, "input", y_unit),
                             _connector(measurements[0].name, "input", y_unit),
                             _connector(manipulated[0].name, "output", u_unit)]
    wiring = (f"setpoint.y -> controller.{setpoints[0].name}", f"plant.{measured.name} -> controller.{measurements[0].name}",
              f"controller.{manipulated[0].name} -> plant.{driven.name}")
    left = []
    if facts is not None:
        wired = {setpoints[0].name, measurements[0].name}
        for port in facts.ports:
            if port.causality == "input" and port.name not in wired:
                left.append(f"controller.{port.name}: the controller's {port.role} input"
                            + (f" (needed when {port.when})" if port.when else "") + "; it keeps its start value "
                            f"{control.variables[port.name].start} until you connect it or bind a value")
    for v in inputs:
        if v.name != driven.name:
            left.append(f"plant.{v.name}: another plant input, kept at its start value {v.start}")
    extra_outputs = [v for v in outputs if v.name != measured.name]
    for port in manipulated[1:] + setpoints[1:] + measurements[1:]:
        left.append(f"controller.{port.name}: a further {port.role} port, not wired (a multivariable controller)")

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copyfile(plant, folder / "resources" / plant_name)
    interface = "ModelExchange" if plant_desc.kind.endswith("-me") else "CoSimulation"
    ssd = _ssd(folder.name, ctrl_name, plant_name, controller_connectors, y_unit, u_unit, measured, driven,
               extra_outputs, y0, final, stop, step, wiring, setpoints[0].name, measurements[0].name,
               manipulated[0].name, interface)
    (folder / "SystemStructure.ssd").write_text(ssd, encoding="utf-8")
    (folder / "controller.ssv").write_text(_ssv(control, ts_name, ts), encoding="utf-8")
    (folder / "README.md").write_text(_readme(folder, ctrl_name, plant_name, wiring, left, ts_name, ts, step, stop),
                                      encoding="utf-8")
    files = tuple(folder / name for name in ("SystemStructure.ssd", "controller.ssv", "README.md",
                                             f"resources/{plant_name}"))
    return NewScenario(folder, files, wiring, tuple(left))


def _ssd(name, ctrl_name, plant_name, controller_connectors, y_unit, u_unit, measured, driven, extra_outputs,
         y0, final, stop, step, wiring, r, y, u, interface) -> str:
    plant_connectors = [_connector(driven.name, "input", u_unit), _connector(measured.name, "output", y_unit)]
    plant_connectors += [_connector(v.name, "output", unit_of(v)) for v in extra_outputs]
    t_step = round(stop / 10, 12)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- Written by `cosim new`: {escape(ctrl_name)} closes a loop around {escape(plant_name)}.
     {'; '.join(escape(w) for w in wiring)}.
     The plant runs through its {interface} interface{' (the master integrates it)' if interface == 'ModelExchange' else ''}.
     The set-point steps from the plant output's start value at t = {t_step:g} s. Tune the controller in
     controller.ssv; README.md says what is left to wire. -->
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0"
    version="1.0" name={quoteattr(name)}>
  <ssd:System name="loop">
    <ssd:Elements>
      <ssd:Component name="setpoint" source="resources/{SETPOINT_FMU}" type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
{_connector("y", "output", y_unit)}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="setpoint">
                <ssv:Parameters>
                  <ssv:Parameter name="t_step"><ssv:Real value="{t_step!r}"/></ssv:Parameter>
                  <ssv:Parameter name="initial"><ssv:Real value="{y0!r}"/></ssv:Parameter>
                  <ssv:Parameter name="final"><ssv:Real value="{final!r}"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="controller" source={quoteattr('resources/' + ctrl_name)} type="application/x-fmu-sharedlibrary">
        <ssd:Connectors>
{chr(10).join(controller_connectors)}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="controller.ssv"/>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="plant" source={quoteattr('resources/' + plant_name)} type="application/x-fmu-sharedlibrary"
          implementation="{interface}">
        <ssd:Connectors>
{chr(10).join(plant_connectors)}
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="setpoint" startConnector="y" endElement="controller" endConnector={quoteattr(r)}/>
      <ssd:Connection startElement="plant" startConnector={quoteattr(measured.name)} endElement="controller" endConnector={quoteattr(y)}/>
      <ssd:Connection startElement="controller" startConnector={quoteattr(u)} endElement="plant" endConnector={quoteattr(driven.name)}/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop!r}">
    <ssd:Annotations>
      <ssc:Annotation type="org.greyfmu.simulation">
        <greyfmu:Simulation stepSize="{step!r}"/>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def _ssv(control: FMUDescription, ts_name: str | None, ts: float | None) -> str:
    lines = []
    for v in control.variables.values():
        if v.causality != "parameter" or v.start is None or v.type not in ("Real", "Integer", "Boolean", "Float64", "Int32"):
            continue
        kind = "Real" if v.type in ("Real", "Float64") else "Integer" if v.type in ("Integer", "Int32") else "Boolean"
        unit = unit_of(v)
        note = escape((v.description or "").replace("--", "-")) + (f" [{escape(unit)}]" if unit else "")
        lines.append(f'    <ssv:Parameter name={quoteattr(v.name)}><ssv:{kind} value={quoteattr(v.start)}/>'
                     f'</ssv:Parameter>  <!-- {note} -->')
    sampled = f" {ts_name} = {ts:g} s is bound so the loop's sampling is chosen here." if ts_name and ts else ""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- Written by `cosim new`: every parameter of {escape(control.path.name)} at its default; tune them here.{sampled} -->
<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="controller">
  <ssv:Parameters>
{chr(10).join(lines)}
  </ssv:Parameters>
</ssv:ParameterSet>
"""


def _readme(folder: Path, ctrl_name, plant_name, wiring, left, ts_name, ts, step, stop) -> str:
    left_text = "\n".join(f"- {item}" for item in left) or "- nothing: every input the controller reads is connected."
    sampled = (f"The controller samples every {ts_name} = {ts:g} s (bound in `controller.ssv`); the master steps "
               f"every {step:g} s, which divides it.") if ts_name and ts else f"The master steps every {step:g} s."
    return f"""# {folder.name}

Written by `cosim new`: `{ctrl_name}` closes a loop around `{plant_name}` (copied into `resources/`).

Wiring: {'; '.join(f'`{w}`' for w in wiring)}. A Step (`setpoint`) moves the set-point from the
plant output's start value at a tenth of the run ({stop:g} s). {sampled}

Left to wire or decide:

{left_text}

Tune the controller in `controller.ssv` (every parameter at its default, with its unit and meaning);
`cosim info resources/{plant_name}` lists the plant's ports and parameters. Run it:

    cosim validate {folder}
    cosim run {folder} --plot
"""
