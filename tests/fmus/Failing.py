"""Test-only FMU: y = t until t reaches fail_time, then it refuses the step.

``raise_error`` = 0: do_step returns False, which pythonfmu 0.7 reports as fmi2Discard;
``raise_error`` = 1: do_step raises, which pythonfmu reports as fmi2Fatal.
"""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status


class Failing(Fmi2Slave):
    description = "Test FMU for the master: y = t, refuses to step past fail_time"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.fail_time = 0.5
        self.raise_error = 1
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("fail_time", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Integer("raise_error", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.tunable))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output, initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        if current_time + step_size > self.fail_time + 1e-12:
            self.log(f"refusing the step from t = {current_time}", Fmi2Status.error)
            if self.raise_error:
                raise RuntimeError(f"failing on purpose at t = {current_time}")
            return False
        self.y = current_time + step_size
        return True
