"""Running: a prepared plan becomes samples.  The step is compiled into a program of operations
(`program`) that two interpreters run bit for bit alike, Python's and the compiled loop of `cosim.kernel`
(`interpreters`), from start to stop (`stepping`), on the exchange buffers (`exchange`) of live
FMU instances (`instances`), an algebraic loop solved by iteration (`loops`); `execution` is the
lifecycle of one run and `simulation` assembles a run and its recording.  Signals stop a run at a
communication point (`interrupts`); `supervisor` runs it in a child process whose crash loses no
recorded row; `outcome` is what a run ends with.
"""
