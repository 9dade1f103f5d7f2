"""Test-only FMU with String ports, for String connections in the master."""
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, String


class Labels(Fmi2Slave):
    description = ("Test FMU for the master: String output label = 'low' before t = 0.5 and 'high' from then on; "
                   "String input text and Integer output length = len(text) (direct feedthrough)")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.label = "low"
        self.text = ""
        self.register_variable(String("label", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete,
                                      initial=Fmi2Initial.exact))
        self.register_variable(String("text", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete))
        self.register_variable(Integer("length", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete, initial=Fmi2Initial.exact,
                                       getter=lambda: len(self.text)))

    def do_step(self, current_time, step_size):
        self.label = "high" if current_time + step_size >= 0.5 else "low"
        return True
