"""Test-only FMU for unit conversion: three Real inputs u_i passed through to outputs v_i = u_i.

The units of u_i and v_i are written into the model description by tests/scenarios/test_units.py, so the
values an FMU receives, in its own unit, can be read back from it.
"""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


class UnitSink(Fmi2Slave):
    description = "Test FMU for the master: v_i = u_i (direct feedthrough), units chosen by the test"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for i in (1, 2, 3):
            setattr(self, f"u{i}", 0.0)
            self.register_variable(Real(f"u{i}", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous))
            self.register_variable(Real(f"v{i}", causality=Fmi2Causality.output, initial=Fmi2Initial.calculated,
                                        getter=lambda i=i: getattr(self, f"u{i}")))

    def do_step(self, current_time, step_size):
        return True
