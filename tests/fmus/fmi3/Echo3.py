"""Test-only FMI 3.0 FMU (pythonfmu3): one input and one computed output of each type the
master exchanges with FMI 3.0 FMUs, and an input array, so each connection is observable."""
import numpy as np
from pythonfmu3 import Boolean, Dimension, Float64, Fmi3Causality, Fmi3Slave, Fmi3StepResult, Fmi3Variability, Int32, String


class Echo3(Fmi3Slave):
    """Outputs, computed from the inputs when read (direct feedthrough):
    twice = 2 n (Int32), negated = not b (Boolean), shout = s.upper() (String),
    total = v[1] + 10 v[2] + 100 v[3] (Float64, v a Float64 input array of 3).
    do_step asks to terminate the simulation (terminateSimulation = true) once n < 0."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "Test FMU for the master (FMI 3.0 types and arrays)"
        self.n, self.b, self.s = 0, False, ""
        self.v = np.zeros(3)
        self.time = 0.0
        discrete = Fmi3Variability.discrete
        self.register_variable(Float64("time", causality=Fmi3Causality.independent))  # FMI 3.0 needs one
        self.register_variable(Int32("n", causality=Fmi3Causality.input, variability=discrete))
        self.register_variable(Boolean("b", causality=Fmi3Causality.input, variability=discrete))
        self.register_variable(String("s", causality=Fmi3Causality.input, variability=discrete))
        # explicit setter: pythonfmu3 0.3.4's default array setter calls numpy.reshape(newshape=...),
        # which numpy 2.4 no longer accepts
        self.register_variable(Float64("v", causality=Fmi3Causality.input, dimensions=[Dimension(start="3")],
                                       setter=lambda values: setattr(self, "v", np.array(values, dtype=float))))
        self.register_variable(Int32("twice", causality=Fmi3Causality.output, variability=discrete,
                                     getter=lambda: 2 * self.n))
        self.register_variable(Boolean("negated", causality=Fmi3Causality.output, variability=discrete,
                                       getter=lambda: not self.b))
        self.register_variable(String("shout", causality=Fmi3Causality.output, variability=discrete,
                                      getter=lambda: self.s.upper()))
        self.register_variable(Float64("total", causality=Fmi3Causality.output,
                                       getter=lambda: float(self.v @ np.array([1.0, 10.0, 100.0]))))

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return Fmi3StepResult(terminateSimulation=self.n < 0)
