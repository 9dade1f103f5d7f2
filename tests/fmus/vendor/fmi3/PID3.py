"""Another vendor's plain pythonfmu3 0.3.4 FMU named like ours (fmus/fmi3/PID3.py): u = 1.5 (r - y)."""
from pythonfmu3 import Float64, Fmi3Causality, Fmi3Slave, Fmi3Variability


class PID3(Fmi3Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "Another vendor's proportional controller u = 1.5 (r - y)"
        self.time = 0.0
        self.r = 0.0
        self.y = 0.0
        self.u = 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("r", causality=Fmi3Causality.input, variability=Fmi3Variability.continuous,
                                       start=0.0))
        self.register_variable(Float64("y", causality=Fmi3Causality.input, variability=Fmi3Variability.continuous,
                                       start=0.0))
        self.register_variable(Float64("u", causality=Fmi3Causality.output, variability=Fmi3Variability.continuous))

    def do_step(self, current_time, step_size, no_set_fmu_state_prior=False):
        self.u = 1.5 * (self.r - self.y)
        self.time = current_time + step_size
        return True
