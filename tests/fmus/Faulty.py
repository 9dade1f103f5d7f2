"""Test-only fault injector: y = t, and from ``fault_time`` on, ``do_step`` does ``fault``:

1 abort() (SIGABRT), 2 a segfault (a NULL read through ctypes), 3 _exit(3) (the process ends
without unwinding), 4 hangs (sleeps for an hour), 5 sleeps ``delay`` seconds per step (slow),
6 limits the process's address space (RLIMIT_AS, as ``ulimit -v`` does) to what it maps then
plus 8 MiB, once, so that the master runs out of memory later in the run.
0 (the default) steps normally.
"""
import ctypes
import os
import resource
import time

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real


class Faulty(Fmi2Slave):
    description = "Test FMU for the master: y = t; aborts, segfaults, exits, hangs or is slow from fault_time"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.fault = 0
        self.fault_time = 0.0
        self.delay = 0.02
        self.y = 0.0
        self.limited = False
        for name, kind in (("fault", Integer), ("fault_time", Real), ("delay", Real)):
            self.register_variable(kind(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.tunable))
        self.register_variable(Real("y", causality=Fmi2Causality.output, initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        if current_time >= self.fault_time - 1e-12:
            if self.fault == 1:
                os.abort()
            elif self.fault == 2:
                ctypes.string_at(0)
            elif self.fault == 3:
                os._exit(3)
            elif self.fault == 4:
                time.sleep(3600)
            elif self.fault == 5:
                time.sleep(self.delay)
            elif self.fault == 6 and not self.limited:
                self.limited = True
                with open("/proc/self/status") as status:
                    mapped = next(int(line.split()[1]) for line in status if line.startswith("VmSize:")) * 1024
                resource.setrlimit(resource.RLIMIT_AS, (mapped + (8 << 20), resource.getrlimit(resource.RLIMIT_AS)[1]))
        self.y = current_time + step_size
        return True
