"""The benchmark floor: the FMI 2.0 Co-Simulation calls a fixed-step Jacobi master must
make, and nothing else, with raw ctypes functions on preallocated arrays.

    elapsed, n_steps, results = run_floor(fmus, connections, start, stop, step, record_vars)

Per macro step and per FMU: one batched ``fmi2SetReal`` (all its connected inputs), one
``fmi2DoStep``, one batched ``fmi2GetReal`` (the outputs it feeds plus the variables to
record), then one NumPy gather for the routing and one for the record row.  The raw
functions are fmpy's ``FMU2Slave._functions['fmi2...']`` (ctypes function pointers with
argtypes set; they return the int status without fmpy's list conversions and checks).

Semantics, chosen to match libcosim (see tests/peers.py and docs/peers.md):

- Jacobi: every FMU steps from t_k with inputs taken from outputs at t_k.
- ``initial_inputs="outputs"`` (default): in initialization mode, len(fmus) passes of
  get outputs -> route -> set inputs (libcosim runs N+F such passes), then
  exitInitializationMode, get, route; so the first step sees the connected outputs'
  initial values.  ``"zero"``: connected inputs get 0.0 for the first step (what
  fmpy.ssp does).  ``"start"``: the FMUs' own start values for the first step.
- Row 0 of the results is the state after initialization (time = start); row k is read
  after the k-th doStep (time = start + k*step).  A recorded input shows the value the
  FMU held during step k, as libcosim's observers do.
- Communication points t_k = start + k*step, step k from t_k with h_k = t_{k+1} - t_k
  (no accumulated rounding; no stop time is given to fmi2SetupExperiment).
- ``elapsed_seconds`` times the stepping loop only (not unzip/instantiate/initialize).
- FMUs are instantiated with loggingOn = false (libcosim has them log; with the gemseo
  OpenModelica FMUs that alone costs tens of µs per step, see docs/peers.md).
"""
from __future__ import annotations

import ctypes
import shutil
import time as _time
from contextlib import contextmanager
from typing import Mapping, Sequence

import numpy as np

__all__ = ["instantiated", "run_floor"]


@contextmanager
def instantiated(fmus: Sequence[tuple[str, str, Mapping[str, float]]], start: float, *,
                 shared_library: bool = False):
    """FMI 2.0 CS instances of ``fmus`` [(name, fmu_path, {variable: start value})], each from its
    own extraction (separate .so copies, as libcosim) or, ``shared_library``, one extraction per
    FMU file (as cosim), set up at ``start`` (no stop time, as libcosim and fmpy.ssp) with the
    start values set; yields (fmpy FMU2Slaves, {name: variable} per instance) and frees the
    instances and extractions afterwards."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    slaves, unzipdirs, variables = [], [], []
    extracted: dict[str, str] = {}
    described: dict[str, object] = {}
    try:
        for name, path, params in fmus:
            md = described.get(path) or described.setdefault(path, read_model_description(path, validate=False))
            if md.fmiVersion != "2.0" or md.coSimulation is None:
                raise ValueError(f"{name}: {path} is not an FMI 2.0 Co-Simulation FMU")
            unzipdir = extracted.get(path) if shared_library else None
            if unzipdir is None:
                unzipdir = extracted[path] = extract(path)
                unzipdirs.append(unzipdir)
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                            modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
            fmu.instantiate()
            slaves.append(fmu)
            vars_ = {v.name: v for v in md.modelVariables}
            variables.append(vars_)
            fmu.setupExperiment(startTime=start)
            for var, value in params.items():
                v = vars_[var]
                if v.type == "Real":
                    fmu.setReal([v.valueReference], [float(value)])
                elif v.type in ("Integer", "Enumeration"):
                    fmu.setInteger([v.valueReference], [int(value)])
                elif v.type == "Boolean":
                    fmu.setBoolean([v.valueReference], [bool(value)])
                else:
                    raise TypeError(f"{name}.{var}: unsupported type {v.type}")
        yield slaves, variables
    finally:
        for fmu in slaves:
            try:
                fmu.freeInstance()
            except Exception:
                pass
        for d in unzipdirs:
            shutil.rmtree(d, ignore_errors=True)


def run_floor(
    fmus: Sequence[tuple[str, str, Mapping[str, float]]],
    connections: Sequence[tuple[str, str, str, str]],
    start: float,
    stop: float,
    step: float,
    record_vars: Sequence[str],
    *,
    initial_inputs: str = "outputs",
) -> tuple[float, int, np.ndarray]:
    """Run FMI 2.0 CS FMUs coupled by ``connections`` with a fixed-step Jacobi loop.

    fmus:         [(name, fmu_path, {variable: start value})], values set after
                  fmi2SetupExperiment, before fmi2EnterInitializationMode.
    connections:  [(src_comp, src_var, dst_comp, dst_var)], output -> input, Real only.
    record_vars:  ["comp.var", ...] Real variables read after every step.
    Returns (elapsed_seconds of the step loop, n_steps, results), results being a
    structured array with ``time`` and one column per record var, n_steps + 1 rows.
    """
    if initial_inputs not in ("outputs", "zero", "start"):
        raise ValueError("initial_inputs must be 'outputs', 'zero' or 'start'")
    n_steps = round((stop - start) / step)
    if n_steps < 1 or abs(start + n_steps * step - stop) > 1e-9 * max(1.0, abs(stop)):
        raise ValueError("(stop - start) must be a whole number of steps")

    names = [name for name, _, _ in fmus]
    if len(set(names)) != len(names):
        raise ValueError("FMU instance names must be unique")

    with instantiated(fmus, start) as (slaves, variables):
        index = {name: i for i, name in enumerate(names)}

        def real_vr(comp: str, var: str) -> int:
            v = variables[index[comp]].get(var)
            if v is None or v.type != "Real":
                raise KeyError(f"{comp}.{var} is not a Real variable")
            return v.valueReference

        # --- precompute: per-FMU get/set value references, flat buffers, index arrays --
        gets = [[] for _ in fmus]  # value references read after each step, per FMU
        sets = [[] for _ in fmus]  # connected inputs, per FMU

        def get_slot(comp: str, var: str) -> tuple[int, int]:
            vr, i = real_vr(comp, var), index[comp]
            if vr not in gets[i]:
                gets[i].append(vr)
            return i, gets[i].index(vr)

        src_slots, dst_slots = [], []
        for sc, sv, dc, dv in connections:
            src_slots.append(get_slot(sc, sv))
            vr, i = real_vr(dc, dv), index[dc]
            if vr in sets[i]:
                raise ValueError(f"{dc}.{dv} is driven by more than one connection")
            sets[i].append(vr)
            dst_slots.append((i, len(sets[i]) - 1))
        rec_slots = []
        for rv in record_vars:
            comp, _, var = rv.partition(".")
            rec_slots.append(get_slot(comp, var))

        get_off = np.cumsum([0] + [len(g) for g in gets])
        set_off = np.cumsum([0] + [len(s) for s in sets])
        y = np.zeros(int(get_off[-1]))  # every value read, all FMUs back to back
        u = np.zeros(int(set_off[-1]))  # every input written
        src = np.array([get_off[i] + j for i, j in src_slots], dtype=np.intp)
        dst = np.array([set_off[i] + j for i, j in dst_slots], dtype=np.intp)
        rec = np.array([get_off[i] + j for i, j in rec_slots], dtype=np.intp)

        # raw ctypes functions with their argument arrays bound once; the value arrays
        # are views into y and u, so the NumPy gathers below move the data
        c_uint, c_double = ctypes.c_uint, ctypes.c_double
        get_calls, set_calls, step_calls, input_reads = [], [], [], []
        for i, fmu in enumerate(slaves):
            f, c = fmu._functions, fmu.component
            if gets[i]:
                n = len(gets[i])
                get_calls.append((f["fmi2GetReal"], c, (c_uint * n)(*gets[i]), n,
                                  (c_double * n).from_buffer(y, int(get_off[i]) * 8)))
            if sets[i]:
                n = len(sets[i])
                set_calls.append((f["fmi2SetReal"], c, (c_uint * n)(*sets[i]), n,
                                  (c_double * n).from_buffer(u, int(set_off[i]) * 8)))
                input_reads.append((f["fmi2GetReal"],) + set_calls[-1][1:])
            step_calls.append((f["fmi2DoStep"], c))

        def call_all(calls, what: str) -> None:
            st = 0
            for fn, c, vr, n, values in calls:
                st |= fn(c, vr, n, values)
            if st > 1:
                raise RuntimeError(f"{what} failed (status bits {st})")

        # --- initialization --------------------------------------------------------------
        for fmu in slaves:
            fmu.enterInitializationMode()
        if initial_inputs == "outputs":
            for _ in slaves:
                call_all(get_calls, "fmi2GetReal")
                u[dst] = y[src]
                call_all(set_calls, "fmi2SetReal")
        for fmu in slaves:
            fmu.exitInitializationMode()
        call_all(get_calls, "fmi2GetReal")
        if initial_inputs == "outputs":
            u[dst] = y[src]
        elif initial_inputs == "zero":
            u[:] = 0.0
        else:  # "start": the FMUs' own input values for the first step
            call_all(input_reads, "fmi2GetReal")

        results = np.empty((n_steps + 1, 1 + len(rec)))
        results[:, 0] = start + step * np.arange(n_steps + 1)
        results[0, 1:] = y[rec]
        grid = results[:, 0].tolist()  # t_k = start + k*step, no accumulated rounding

        # --- the step loop ---------------------------------------------------------------
        t0 = _time.perf_counter()
        for k in range(n_steps):
            t = grid[k]
            h = grid[k + 1] - t  # t + h = t_{k+1} up to the last bit, no drift
            st = 0
            for fn, c, vr, n, values in set_calls:
                st |= fn(c, vr, n, values)
            for fn, c in step_calls:
                st |= fn(c, t, h, 1)  # noSetFMUStatePriorToCurrentPoint = true
            for fn, c, vr, n, values in get_calls:
                st |= fn(c, vr, n, values)
            if st > 1:  # any status above fmi2Warning sets a bit above 1
                raise RuntimeError(f"an FMI call failed in step {k} (t = {t}): status bits {st}")
            results[k + 1, 1:] = y[rec]
            u[dst] = y[src]
        elapsed = _time.perf_counter() - t0

        for fmu in slaves:
            fmu.terminate()

    dtype = np.dtype([("time", "f8")] + [(name, "f8") for name in record_vars])
    return elapsed, n_steps, results.view(dtype).reshape(n_steps + 1)
