"""The C floor: benchmarks/native_floor.c, compiled here and called through ctypes, steps FMI 2.0
Co-Simulation instances that fmpy has loaded (`floor.instantiated`, one library per FMU file,
as cosim loads them).

    library = compile_floor(folder)
    seconds, results = run_c_floor(library, fmus, outputs, connections, feedthrough, start, stop, step)

Python instantiates, sets the start values and initialises; the step loop (fmi2DoStep, one
batched fmi2GetReal and fmi2SetReal per instance, the routing, the record of the time and every
output and input: into a C array, ``csv=PATH`` as CSV lines written by cosim's C formatter,
``record=False`` nowhere) runs in C and times itself.  ``settle=True`` is cosim's exchange (direct
feedthrough settled in dependency order within the instant, cosim/run/execution.py), ``False`` plain
Jacobi (libcosim, the fmu-manipulation-toolbox container).  Initialisation is cosim's: the
exchange once in initialization mode and once after it; row 0 of the results is the state after
it, row k the state after step k, t_k on cosim's grid.
"""
from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from floor import instantiated

__all__ = ["compile_floor", "run_c_floor"]

SOURCE = Path(__file__).resolve().parent / "native_floor.c"
#: cosim's compiled CSV formatter (and the Ryu it includes), compiled into the floor
KERNEL = Path(__file__).resolve().parents[1] / "cosim" / "kernel"

_p = ctypes.POINTER


class _Floor(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("component", _p(ctypes.c_void_p)), ("do_step", _p(ctypes.c_void_p)),
                ("get", _p(ctypes.c_void_p)), ("set", _p(ctypes.c_void_p)),
                ("get_vr", _p(ctypes.c_uint)), ("get_off", _p(ctypes.c_int)),
                ("set_vr", _p(ctypes.c_uint)), ("set_off", _p(ctypes.c_int)),
                ("source", _p(ctypes.c_int)), ("feedthrough", _p(ctypes.c_int)),
                ("y", _p(ctypes.c_double)), ("u", _p(ctypes.c_double)), ("settle", ctypes.c_int)]


class _Failure(ctypes.Structure):
    _fields_ = [("instance", ctypes.c_int), ("step", ctypes.c_long), ("status", ctypes.c_int)]


def compile_floor(folder: Path) -> Path:
    """native_floor.c (with cosim's csvrows.c) compiled (-O2, as setup.py builds the kernel) with the
    system C compiler into ``folder``: the library's path."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise RuntimeError("no C compiler (cc or gcc) on PATH: benchmarks/native_floor.c cannot be built")
    library = Path(folder) / "native_floor.so"
    subprocess.run([compiler, "-O2", "-Wall", "-Werror", "-shared", "-fPIC", f"-I{KERNEL}", "-o", str(library),
                    str(SOURCE), str(KERNEL / "csvrows.c")], check=True, capture_output=True, text=True)
    return library


def _load(library: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(library))   # loaded once per process: dlopen of the same path shares it
    lib.floor_exchange.argtypes = [_p(_Floor), _p(_Failure)]
    lib.floor_run.argtypes = [_p(_Floor), ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_long,
                              _p(ctypes.c_double), ctypes.c_int, _p(ctypes.c_double), _p(_Failure)]
    return lib


def _pointer(array: np.ndarray, ctype):
    return array.ctypes.data_as(_p(ctype))


def run_c_floor(
    library: Path,
    fmus: Sequence[tuple[str, str, Mapping[str, float]]],
    outputs: Mapping[str, Sequence[str]],
    connections: Sequence[tuple[str, str, str, str]],
    feedthrough: Sequence[str],
    start: float,
    stop: float,
    step: float,
    *,
    settle: bool = True,
    record: bool = True,
    csv: Path | None = None,
    clock=None,
) -> tuple[float, np.ndarray]:
    """Run ``fmus`` [(name, fmu_path, {variable: start value})] from ``start`` to ``stop``.

    outputs:      the Real outputs read after every step, per instance;
    connections:  [(src, src_var, dst, dst_var)], output -> input, factor 1, offset 0; the
                  inputs set are exactly the connected ones;
    feedthrough:  the instances whose outputs depend on their inputs, in dependency order.
    Returns (the loop's seconds, a structured array: ``time`` and ``comp.var`` for every output
    and every connected input, one row per communication point).  ``library``: `compile_floor`'s.
    ``csv``: the rows written to that file instead (a quoted header as cosim's, then one line per
    step after the first row; the array returned is then empty); ``record`` False: the rows
    recorded nowhere (the array is empty).  ``clock``: a function of no arguments (e.g.
    ``time.process_time``) whose difference across the loop is returned instead of the loop's
    wall time, the array or file recording included (its pages are touched in the loop).
    """
    lib = _load(library)
    names = [name for name, _, _ in fmus]
    if len(set(names)) != len(names):
        raise ValueError("FMU instance names must be unique")
    unknown = [c for c in feedthrough if c not in names]
    if unknown:
        raise KeyError(f"feedthrough instances {unknown} are not among the FMUs {names}")
    order = [c for c in names if c not in feedthrough] + list(feedthrough)
    n_steps = max(1, int(np.ceil((stop - start) / step - 1e-9)))
    inputs: dict[str, list[str]] = {c: [] for c in order}
    for _, _, dst, dst_var in connections:
        inputs[dst].append(dst_var)
    y_names = [f"{c}.{v}" for c in order for v in outputs.get(c, ())]
    u_names = [f"{c}.{v}" for c in order for v in inputs[c]]
    y_index = {name: j for j, name in enumerate(y_names)}
    source = np.array([y_index[f"{src}.{sv}"] for c in order for v in inputs[c]
                       for src, sv, dst, dv in connections if (dst, dv) == (c, v)], dtype=np.intc)

    with instantiated([fmus[names.index(c)] for c in order], start, shared_library=True) as (slaves, variables):
        def vrs(i: int, var_names: Sequence[str]) -> list[int]:
            found = [variables[i].get(v) for v in var_names]
            missing = [f"{order[i]}.{v}" for v, x in zip(var_names, found) if x is None or x.type != "Real"]
            if missing:
                raise KeyError(f"{missing}: not Real variables of their FMUs")
            return [x.valueReference for x in found]

        get_vr = np.array([vr for i, c in enumerate(order) for vr in vrs(i, outputs.get(c, ()))], dtype=np.uintc)
        set_vr = np.array([vr for i, c in enumerate(order) for vr in vrs(i, inputs[c])], dtype=np.uintc)
        get_off = np.cumsum([0] + [len(outputs.get(c, ())) for c in order]).astype(np.intc)
        set_off = np.cumsum([0] + [len(inputs[c]) for c in order]).astype(np.intc)
        flags = np.array([c in feedthrough for c in order], dtype=np.intc)
        y, u = np.zeros(len(y_names)), np.zeros(len(u_names))
        functions = {key: np.array([ctypes.cast(s._functions[f"fmi2{key}"], ctypes.c_void_p).value for s in slaves],
                                   dtype=np.uintp) for key in ("DoStep", "GetReal", "SetReal")}
        components = np.array([ctypes.cast(s.component, ctypes.c_void_p).value for s in slaves], dtype=np.uintp)
        floor = _Floor(len(order), _pointer(components, ctypes.c_void_p), _pointer(functions["DoStep"], ctypes.c_void_p),
                       _pointer(functions["GetReal"], ctypes.c_void_p), _pointer(functions["SetReal"], ctypes.c_void_p),
                       _pointer(get_vr, ctypes.c_uint), _pointer(get_off, ctypes.c_int),
                       _pointer(set_vr, ctypes.c_uint), _pointer(set_off, ctypes.c_int),
                       _pointer(source, ctypes.c_int), _pointer(flags, ctypes.c_int),
                       _pointer(y, ctypes.c_double), _pointer(u, ctypes.c_double), int(settle))
        failure = _Failure()

        def check(failed: int, what: str) -> None:
            if failed:
                where = "before the first step" if failure.step < 0 else f"in step {failure.step}"
                raise RuntimeError(f"C floor: {what} of instance '{order[failure.instance]}' returned status "
                                   f"{failure.status} {where}")

        for slave in slaves:
            slave.enterInitializationMode()
        check(lib.floor_exchange(ctypes.byref(floor), ctypes.byref(failure)), "the exchange")
        for slave in slaves:
            slave.exitInitializationMode()
        check(lib.floor_exchange(ctypes.byref(floor), ctypes.byref(failure)), "the exchange")
        names = ["time"] + y_names + u_names
        seconds = ctypes.c_double()
        began = clock() if clock is not None else 0.0
        if csv is not None:
            with open(csv, "wb") as file:
                file.write((",".join('"' + n + '"' for n in names) + "\n").encode())
                file.flush()
                check(lib.floor_run(ctypes.byref(floor), start, stop, step, n_steps, None, file.fileno(),
                                    ctypes.byref(seconds), ctypes.byref(failure)), "a call (or the write)")
            rows = np.empty((0, len(names)))
        else:
            rows = np.empty((n_steps + 1 if record else 0, len(names)))
            if record:
                rows[0] = np.concatenate([[start], y, u])
            check(lib.floor_run(ctypes.byref(floor), start, stop, step, n_steps,
                                _pointer(rows[1:], ctypes.c_double) if record else None, -1,
                                ctypes.byref(seconds), ctypes.byref(failure)), "a call")
        if clock is not None:
            seconds.value = clock() - began
        for slave in slaves:
            slave.terminate()

    results = rows.view(np.dtype([(name, "f8") for name in names]))[:, 0]
    return seconds.value, results
