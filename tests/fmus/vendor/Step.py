"""Another vendor's plain pythonfmu 0.7.0 FMU named like ours (fmus/Step.py): y = 7 from t = 0.5 s on."""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


class Step(Fmi2Slave):
    description = "Another vendor's step: y = 7 from t = 0.5 s on, 0 before"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.y = 0.0
        self.register_variable(Real("y", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                                    initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        self.y = 7.0 if current_time + step_size >= 0.5 else 0.0
        return True
