"""Test-only FMU for unit conversion: three Real outputs y_i = a_i + b·t.

The units of y_i and a_i are written into the model description by tests/scenarios/test_units.py
(pythonfmu 0.7.0 variables cannot declare one), so one build serves every unit combination.
"""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


class UnitSource(Fmi2Slave):
    description = "Test FMU for the master: ramps y_i = a_i + b*t whose units the test chooses"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.b = 1.0
        self.register_variable(Real("b", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        for i, a in ((1, 20.0), (2, 10.0), (3, 50.0)):
            setattr(self, f"a{i}", a)
            self.register_variable(Real(f"a{i}", causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
            self.register_variable(Real(f"y{i}", causality=Fmi2Causality.output, initial=Fmi2Initial.calculated,
                                        getter=lambda i=i: getattr(self, f"a{i}") + self.b * self.time))

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.time = start_time

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
