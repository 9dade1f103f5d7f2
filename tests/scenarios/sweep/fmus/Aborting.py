"""Test-only FMU: y = t, and the whole process aborts (os.abort(), SIGABRT) once t reaches
``abort_time``: an FMU that crashes its host, for the sweep's worker-process tests."""
import os

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


class Aborting(Fmi2Slave):
    description = "Test FMU for cosim sweep: y = t, calls os.abort() at abort_time"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.abort_time = 1e9
        self.y = 0.0
        self.register_variable(Real("abort_time", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("y", causality=Fmi2Causality.output, initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        if current_time + step_size > self.abort_time + 1e-12:
            os.abort()
        self.y = current_time + step_size
        return True
