"""Model Exchange FMUs hosted by the master: the master integrates their states.

An FMI 2.0 Model Exchange FMU has no ``fmi2DoStep``; it gives derivatives and
event indicators, and the importer integrates (FMI 2.0 §3).  `MEInstance`
wraps fmpy's `FMU2Model` behind the same small interface as a Co-Simulation
`cosim.run.instances.fmi2.FMI2Instance`, so the execution steps it like any other component
(`ME3Instance` does the same for FMI 3.0 on fmpy's `FMU3Model`, FMI 3.0 §3; the integration
both share is `Integrated`):
``do_step(component, t, h, flag)`` integrates from t to t + h with the inputs
held (zero-order hold) using fmpy's `CVodeSolver` (SUNDIALS CVODE, BDF with a
dense Newton solver, so stiff plants are stable at any communication step).

Events (FMI 2.0 §3.2.2 for the functions, §3.2.3 for the state machine, §3.2.4
for the reference loop this follows):

* input events: an input changed at the communication point is a
  discontinuity: the FMU goes through Event Mode (relations that depend on the
  input are re-evaluated) and the solver restarts at t;
* time events: ``eventInfo.nextEventTime`` caps the integration interval;
* state events: event-indicator sign changes, located by CVODE's root finding;
* step events: ``fmi2CompletedIntegratorStep`` asks for Event Mode.

Each one is fmi2EnterEventMode, the fmi2NewDiscreteStates iteration until no
new discrete states are needed, fmi2EnterContinuousTimeMode, and a solver
restart from the FMU's (possibly re-initialised) states.  terminateSimulation
ends the run as a Discard does.  ``do_step`` never raises: an FMU call that
fails returns its status, a solver failure returns Error (3), and the reason
is in ``messages``.
"""
from __future__ import annotations

import ctypes
import math

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, fmi2EventInfo, fmi2False
from fmpy.fmi3 import FMU3Model

from ...errors import SetupError
from ...model.fmu import FMUDescription, Variable
from ...model.structure import SolverSettings
from .base import STATUS
from .loading import quick
from .fmi2 import FMI2Instance
from .fmi3 import FMI3Instance

FMI_OK, FMI_DISCARD, FMI_ERROR = 0, 2, 3
#: Events handled within one communication step before the FMU is declared to chatter.
MAX_EVENTS_PER_STEP = 1000
#: fmi2NewDiscreteStates / fmi3UpdateDiscreteStates calls in one Event Mode before the FMU is
#: declared not to converge (FMI 2.0 §3.2.4's loop has no bound; a model that needs more
#: super-dense iterations than this at one time instant is stuck).
MAX_DISCRETE_ITERATIONS = 1000


class _NoInput:
    """fmpy's CVodeSolver re-applies input signals in its root function; inputs here are
    set by the execution and held, so there is nothing to apply."""

    def apply(self, time: float, continuous: bool = True, discrete: bool = True, after_event: bool = False):
        pass


class Integrated:
    """The master's integration of a Model Exchange FMU (see the module docstring), for either
    FMI version: the instance classes give the FMI calls that differ (`MEInstance` for FMI 2.0,
    `ME3Instance` for FMI 3.0): ``_solver_functions`` (the raw functions CVODE calls back, by
    role), ``_discrete_iteration`` and ``_read_inputs``."""

    #: role -> raw FMI function name, for `_new_solver`
    _solver_functions: dict[str, str]

    def __init__(self, name: str, desc: FMUDescription, unzip_dir: str, settings: SolverSettings):
        super().__init__(name, desc, unzip_dir)  # the FMI 2.0 or FMI 3.0 instance (next in the MRO)
        self.settings = settings
        self._raw = self.slave._functions
        self._nx = desc.continuous_states
        self._nz = desc.event_indicators
        self._needs_completed_step = desc.needs_completed_integrator_step
        inputs = [v for v in desc.variables.values() if v.causality == "input" and v.type in ("Real", "Float64")]
        self._input_vrs = (ctypes.c_uint * max(1, len(inputs)))(*(v.vr for v in inputs))
        self._n_inputs = len(inputs)
        #: values behind them: an FMI 3.0 array input holds the product of its extents (§2.4.7.5)
        self._n_input_values = sum(_values(v) for v in inputs)
        self._inputs = (ctypes.c_double * max(1, self._n_input_values))()
        self._held = b""
        self._solver = None
        self._max_step = math.inf
        self._start = 0.0
        self._next_event: float | None = None
        self._ended_at: float | None = None  # where the FMU asked to terminate (`step_end`)
        self._callback_failure: tuple[int, str] | None = None
        self._events = {"input": 0, "time": 0, "state": 0, "step": 0}
        self._event_time = 0.0  # the time of the Event Mode under way, for `_not_converging`

    @property
    def events(self) -> dict[str, int]:
        """Events handled so far, by kind."""
        return dict(self._events)

    def exit_initialization_mode(self) -> None:
        """Leave Initialization Mode, then run the initial event iteration and enter
        Continuous-Time Mode (the model is in Event Mode after exitInitializationMode, FMI 2.0
        §3.2.3 and §3.2.4's loop, FMI 3.0 §3.2), so outputs reflect the initial state; start the
        solver."""
        self.slave.exitInitializationMode()
        self._event_time = self._start
        if self._discrete_iteration():
            raise RuntimeError("the FMU requested termination during its initial event iteration")
        self.slave.enterContinuousTimeMode()
        self._held = self._read_inputs()
        self._solver = self._new_solver()

    def _new_solver(self):
        from fmpy.sundials import CVodeSolver
        f = {role: self._checked(name) for role, name in self._solver_functions.items()}
        return CVodeSolver(nx=self._nx, nz=self._nz, get_x=f["get_x"], set_x=f["set_x"], get_dx=f["get_dx"],
                           get_z=f["get_z"], get_nominals=f["get_nominals"], set_time=f["set_time"],
                           input=_NoInput(), startTime=self._start, relativeTolerance=self.settings.rtol)

    def free(self) -> None:
        """Free the solver (its callbacks call into the FMU), then the instance."""
        self._solver = None
        super().free()

    def _checked(self, function: str):
        """The raw FMI function bound to this instance, for the solver's callbacks: a status
        above Warning is kept (a ctypes callback cannot raise) and reported by do_step."""
        raw = self._raw[function]

        def call(*args):
            status = raw(self.component, *args)
            if status > 1 and self._callback_failure is None:
                self._callback_failure = (status, function)
            return status
        return call

    # ----------------------------------------------------------------- stepping

    def do_step(self, component, t: float, h: float, no_prior_state: int = 1) -> int:
        """Integrate from t to t + h with the inputs held; the FMU's time and states are left at
        t + h so its outputs there can be read.  Returns an FMI status and never raises."""
        try:
            return self._advance(t, t + h)
        except FMICallException as e:
            self.messages.append(f"[{STATUS.get(e.status, e.status)}] {e}")
            return e.status
        except Exception as e:  # the solver's failure (CVODE error flags) or a chattering FMU
            self.messages.append(f"[Error] {type(e).__name__}: {e}")
            return FMI_ERROR

    def _advance(self, t: float, t_end: float) -> int:
        max_step = t_end - t if self.settings.max_step is None else min(self.settings.max_step, t_end - t)
        if not math.isclose(max_step, self._max_step, rel_tol=1e-9):
            from fmpy.sundials.cvode import CVodeSetMaxStep
            self._max_step = max_step
            CVodeSetMaxStep(self._solver.cvode_mem, max_step)
        held = self._read_inputs()
        if held != self._held:  # inputs jumped at t: an event, then a fresh solver start
            self._held = held
            if self._event(t, ["input"]):
                return self._terminated(t)
        time = t
        events = 0
        while not _reached(time, t_end):
            if self._next_event is not None and _reached(time, self._next_event):
                kinds = ["time"]  # a time event due now: no integration first
            else:
                target = t_end if self._next_event is None else min(t_end, self._next_event)
                state_event, _, time = self._solver.step(time, target)
                if self._callback_failure is not None:
                    return self._callback_status(time)
                self.slave.setTime(time)
                step_event = False
                if self._needs_completed_step:
                    step_event, terminate = self.slave.completedIntegratorStep()
                    if terminate:
                        return self._terminated(time)
                time_event = self._next_event is not None and _reached(time, self._next_event)
                kinds = [kind for kind, happened in (("time", time_event), ("state", state_event),
                                                     ("step", step_event)) if happened]
            if kinds:
                events += 1
                if events > MAX_EVENTS_PER_STEP:
                    raise RuntimeError(f"more than {MAX_EVENTS_PER_STEP} events between t = {t:g} and "
                                       f"{t_end:g} (the FMU chatters at t = {time:g})")
                if self._event(time, kinds):
                    return self._terminated(time)
        if time != t_end:  # the grid time exactly, so outputs are read at t + h
            self.slave.setTime(t_end)
        return FMI_OK

    def _event(self, time: float, kinds: list[str]) -> bool:
        """Event Mode at ``time``: the discrete-state iteration, back to Continuous-Time Mode,
        solver restart from the FMU's states (FMI 2.0 §3.2.2).  True if the FMU asks to stop."""
        for kind in kinds:
            self._events[kind] += 1
        self._event_time = time
        self.slave.enterEventMode()
        if self._discrete_iteration():
            return True
        self.slave.enterContinuousTimeMode()
        self._solver.reset(time)
        return False

    def _callback_status(self, time: float) -> int:
        status, function = self._callback_failure
        self._callback_failure = None
        self.messages.append(f"[{STATUS.get(status, status)}] {function} failed while integrating near "
                             f"t = {time:g}")
        return status

    def _not_converging(self, function: str, flag: str) -> RuntimeError:
        """The error for a discrete-state iteration that keeps asking for more."""
        return RuntimeError(f"component '{self.name}': {function} still sets {flag} after "
                            f"{MAX_DISCRETE_ITERATIONS} iterations at t = {self._event_time:g} "
                            "(the event iteration does not converge)")

    def _terminated(self, time: float) -> int:
        self.messages.append(f"[Discard] the FMU requested terminateSimulation at t = {time:g}")
        self._ended_at = time
        return FMI_DISCARD

    def step_end(self, t: float, h: float) -> tuple[float | None, str]:
        """After ``do_step`` ended the run: the FMU asked to terminate at the time its states and
        outputs had reached (an event at t + h leaves the step's outputs valid: that point is
        recorded, as fmpy records it)."""
        return self._ended_at, "it requested terminateSimulation (Model Exchange)"

class MEInstance(Integrated, FMI2Instance):
    """One FMI 2.0 Model Exchange instance stepped like a Co-Simulation slave.

    ``get``/``set`` are the FMU's raw fmi2Get/fmi2Set functions.  ``events`` counts the
    events handled by kind ("input", "time", "state", "step").  The set-up calls, the log
    messages and ``free`` are `FMI2Instance`'s.
    """

    interface = quick(FMU2Model)
    _solver_functions = {"get_x": "fmi2GetContinuousStates", "set_x": "fmi2SetContinuousStates",
                         "get_dx": "fmi2GetDerivatives", "get_z": "fmi2GetEventIndicators",
                         "get_nominals": "fmi2GetNominalsOfContinuousStates", "set_time": "fmi2SetTime"}

    def setup_experiment(self, start: float, stop: float) -> None:
        """fmi2SetupExperiment with the solver's tolerance (the FMU may use it internally)."""
        self._start = start
        self.slave.setupExperiment(tolerance=self.settings.rtol, startTime=start, stopTime=stop)

    def _discrete_iteration(self) -> bool:
        """fmi2NewDiscreteStates until no new discrete states are needed, at most
        `MAX_DISCRETE_ITERATIONS` times; keeps the next time event.  True if the FMU asks to
        terminate.  Each call gets a fresh zeroed fmi2EventInfo, as fmpy's ``newDiscreteStates``
        does: an FMU that only ever sets newDiscreteStatesNeeded (never writes fmi2False) then
        ends the iteration instead of hanging it."""
        for _ in range(MAX_DISCRETE_ITERATIONS):
            info = fmi2EventInfo()
            self.slave.fmi2NewDiscreteStates(self.component, ctypes.byref(info))
            if info.terminateSimulation != fmi2False:
                return True
            if info.newDiscreteStatesNeeded == fmi2False:
                self._next_event = info.nextEventTime if info.nextEventTimeDefined != fmi2False else None
                return False
        raise self._not_converging("fmi2NewDiscreteStates", "newDiscreteStatesNeeded")

    def _read_inputs(self) -> bytes:
        """The inputs as set by the execution (fmi2GetReal on every input), to detect a jump."""
        if not self._n_inputs:
            return b""
        status = self._raw["fmi2GetReal"](self.component, self._input_vrs, self._n_inputs, self._inputs)
        if status > 1:
            raise FMICallException(function="fmi2GetReal", status=status)
        return bytes(self._inputs)



class ME3Instance(Integrated, FMI3Instance):
    """One FMI 3.0 Model Exchange instance, integrated as `MEInstance` integrates FMI 2.0 ones
    (FMI 3.0 §3: the same states, derivatives, event indicators and modes; the discrete-state
    iteration is fmi3UpdateDiscreteStates).  Exchange and set-up are `FMI3Instance`'s."""

    interface = quick(FMU3Model)
    instantiate_function = "fmi3InstantiateModelExchange"
    _solver_functions = {"get_x": "fmi3GetContinuousStates", "set_x": "fmi3SetContinuousStates",
                         "get_dx": "fmi3GetContinuousStateDerivatives", "get_z": "fmi3GetEventIndicators",
                         "get_nominals": "fmi3GetNominalsOfContinuousStates", "set_time": "fmi3SetTime"}

    def setup_experiment(self, start: float, stop: float) -> None:
        self._start = start
        FMI3Instance.setup_experiment(self, start, stop)

    def enter_initialization_mode(self) -> None:
        self.slave.enterInitializationMode(tolerance=self.settings.rtol, startTime=self._start, stopTime=self._stop)

    def _discrete_iteration(self) -> bool:
        """fmi3UpdateDiscreteStates until no update is needed, at most `MAX_DISCRETE_ITERATIONS`
        times; keeps the next time event.  True if the FMU asks to terminate."""
        for _ in range(MAX_DISCRETE_ITERATIONS):  # fmpy passes fresh zeroed flags on every call
            needed, terminate, _, _, next_defined, next_time = self.slave.updateDiscreteStates()
            if terminate:
                return True
            if not needed:
                self._next_event = next_time if next_defined else None
                return False
        raise self._not_converging("fmi3UpdateDiscreteStates", "discreteStatesNeedUpdate")

    def _read_inputs(self) -> bytes:
        if not self._n_inputs:
            return b""
        status = self._raw["fmi3GetFloat64"](self.component, self._input_vrs, self._n_inputs, self._inputs,
                                             self._n_input_values)
        if status > 1:
            raise FMICallException(function="fmi3GetFloat64", status=status)
        return bytes(self._inputs)


def _values(variable: Variable) -> int:
    """How many values ``variable`` holds: 1, or an FMI 3.0 array's product of extents."""
    if any(extent is None for extent in variable.dimensions):
        raise SetupError(f"the Model Exchange input {variable.name} is an array whose extent is not a whole number "
                         "(its Dimension's start or structural parameter): its values cannot be read.",
                         variable=variable.name)
    return math.prod(variable.dimensions)


def _reached(time: float, target: float) -> bool:
    """``time`` is at or past ``target`` up to rounding (grid times are computed, not summed)."""
    return time >= target or math.isclose(time, target, rel_tol=1e-12, abs_tol=1e-14)
