"""Another vendor's plain pythonfmu 0.7.0 FMU named like ours (fmus/PID.py): u = 1.5 (r - y), nothing
of greyfmu.  tests/slaves/test_together.py runs it in one process with ours, in any order."""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


class PID(Fmi2Slave):
    description = "Another vendor's proportional controller u = 1.5 (r - y)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.r = 0.0
        self.y = 0.0
        self.u = 0.0
        self.register_variable(Real("r", causality=Fmi2Causality.input, variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.input, variability=Fmi2Variability.continuous))
        self.register_variable(Real("u", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        self.u = 1.5 * (self.r - self.y)
        return True
