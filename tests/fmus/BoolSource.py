"""Test-only FMU with a Boolean output, to check that Real/Boolean miswiring is refused."""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability


class BoolSource(Fmi2Slave):
    description = "Test FMU for the master: a Boolean output that is true from t >= 1"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.on = False
        self.register_variable(Boolean("on", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                                       initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        self.on = current_time + step_size >= 1.0
        return True
