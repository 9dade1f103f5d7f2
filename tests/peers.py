"""Peer co-simulation masters (libcosim, fmpy.ssp) run in this process, for cross-checks
and benchmarks of our own master, plus a hand-written SSP 1.0 test system.

Everything here was checked by experiment with fmpy 0.3.32, libcosimpy 0.0.6 (bundled
libcosim/libcosimc 0.11.2) and gemseo-fmu 3.1.1 on Linux x86_64, Python 3.11; see
docs/peers.md for the findings and tests/peers/test_peers_smoke.py for the checks.

API
---
- ``gemseo_fmu_dir()``: folder with gemseo-fmu's Linux FMUs (without importing gemseo_fmu).
- ``write_mass_spring_ssp(path, ...)``: the MassSpringSubSystem1 + MassSpringSubSystem2
  system as a ``.ssp`` archive (options to add parameter bindings, a LinearTransformation ...).
- ``run_libcosim(ssp, start, stop, step, signals)`` and
  ``run_fmpy_ssp(ssp, start, stop, step, signals)``: structured arrays with a ``time``
  column and one column per ``"component.variable"`` signal.
"""
from __future__ import annotations

import ctypes
import importlib.util
import math
import time as _time
import zipfile
from pathlib import Path
from typing import Mapping, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

GEMSEO_FMU_PIN = "gemseo-fmu==3.1.1"

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"


# ---------------------------------------------------------------------------------------
# third-party FMUs
# ---------------------------------------------------------------------------------------

def gemseo_fmu_dir() -> Path:
    """Folder holding gemseo-fmu's Linux FMUs (``Mass_Damper.fmu``, ``MassSpringSubSystem1.fmu`` ...).

    Located with ``importlib.util.find_spec`` so that gemseo_fmu (and its heavy,
    not-installed dependencies) is never imported.  Raises ``RuntimeError`` with the
    install command if the package or the folder is missing.
    """
    hint = f"install it with: python -m pip install --no-deps {GEMSEO_FMU_PIN}"
    spec = importlib.util.find_spec("gemseo_fmu")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"gemseo_fmu is not installed; {hint}")
    folder = Path(list(spec.submodule_search_locations)[0]) / "problems" / "fmu_files" / "linux"
    if not (folder / "MassSpringSubSystem1.fmu").is_file():
        raise RuntimeError(f"gemseo_fmu FMUs not found in {folder}; {hint}")
    return folder


# ---------------------------------------------------------------------------------------
# hand-written SSP 1.0 test system
# ---------------------------------------------------------------------------------------

#: connectors of the two halves: (name, kind); every declared input is connected.
MASS_SPRING_CONNECTORS = {
    "sub1": [("x2", "input"), ("x1", "output"), ("v1", "output")],
    "sub2": [("x1", "input"), ("x2", "output"), ("v2", "output")],
}
MASS_SPRING_FMUS = {"sub1": "MassSpringSubSystem1.fmu", "sub2": "MassSpringSubSystem2.fmu"}
#: (startElement, startConnector, endElement, endConnector): data flows output -> input
MASS_SPRING_CONNECTIONS = [("sub1", "x1", "sub2", "x1"), ("sub2", "x2", "sub1", "x2")]


def _parameter_set_xml(name: str, params: Mapping[str, float], ns_decl: str = "") -> str:
    rows = "".join(
        f'<ssv:Parameter name={quoteattr(k)}><ssv:Real value="{float(v)!r}"/></ssv:Parameter>'
        for k, v in params.items()
    )
    return f'<ssv:ParameterSet{ns_decl} version="1.0" name={quoteattr(name)}><ssv:Parameters>{rows}</ssv:Parameters></ssv:ParameterSet>'


def write_mass_spring_ssp(
    path: str | Path,
    *,
    params: Mapping[str, Mapping[str, float]] | None = None,
    params_via: str = "inline",
    transform: tuple[float, float] | None = None,
    transform_ns: str = "ssc",
    connector_types: bool = True,
    extra_connectors: Mapping[str, Sequence[tuple[str, str]]] | None = None,
    default_experiment: tuple[float, float] | None = (0.0, 10.0),
    prefixes: tuple[str, str, str] = ("ssd", "ssc", "ssv"),
    fmu_dir: Path | None = None,
) -> Path:
    """Write the MassSpringSubSystem1/2 coupled system as an SSP 1.0 archive.

    Components ``sub1`` (MassSpringSubSystem1: input x2, outputs x1, v1) and ``sub2``
    (MassSpringSubSystem2: input x1, outputs x2, v2), connections sub1.x1 -> sub2.x1 and
    sub2.x2 -> sub1.x2, FMUs stored as ``resources/<model>.fmu``.

    params:       {"sub1": {"k1": 2.0}} -> a ParameterBinding per component, either inline
                  (``params_via="inline"``: ssd:ParameterValues/ssv:ParameterSet) or in a
                  separate ``<comp>.ssv`` file (``params_via="ssv"``, source="<comp>.ssv").
    transform:    (factor, offset) -> a LinearTransformation on sub1.x1 -> sub2.x1, in the
                  ``transform_ns`` namespace prefix ("ssc" is SSP 1.0; fmpy reads "ssd").
    connector_types: write ``<ssc:Real/>`` inside each Connector.
    extra_connectors: additional connectors per component, e.g. {"sub1": [("k1", "parameter")]}.
    default_experiment: (startTime, stopTime) or None to omit ssd:DefaultExperiment.
    prefixes:     namespace prefixes used for ssd/ssc/ssv (the namespaces stay SSP 1.0).
    """
    path = Path(path)
    fmu_dir = gemseo_fmu_dir() if fmu_dir is None else Path(fmu_dir)
    d, c, v = prefixes
    params = params or {}
    extra_connectors = extra_connectors or {}

    def tag(text: str) -> str:  # apply the chosen prefixes ("" = default namespace)
        for old, new in (("ssd:", d), ("ssc:", c), ("ssv:", v)):
            text = text.replace(old, f"{new}:" if new else "")
        return text

    ssv_files: dict[str, str] = {}
    elements = []
    for comp, model in MASS_SPRING_FMUS.items():
        conns = []
        for name, kind in list(MASS_SPRING_CONNECTORS[comp]) + list(extra_connectors.get(comp, [])):
            body = "<ssc:Real/>" if connector_types else ""
            conns.append(f'<ssd:Connector name="{name}" kind="{kind}">{body}</ssd:Connector>')
        binding = ""
        if comp in params:
            if params_via == "inline":
                binding = ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                           + _parameter_set_xml(f"{comp}_params", params[comp])
                           + "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>")
            elif params_via == "ssv":
                ssv_files[f"{comp}.ssv"] = ('<?xml version="1.0" encoding="UTF-8"?>\n'
                                            + _parameter_set_xml(f"{comp}_params", params[comp],
                                                                 f' xmlns:ssv="{SSV_NS}"'))
                binding = (f'<ssd:ParameterBindings><ssd:ParameterBinding source="{comp}.ssv"/>'
                           "</ssd:ParameterBindings>")
            else:
                raise ValueError(f"params_via must be 'inline' or 'ssv', not {params_via!r}")
        elements.append(
            f'<ssd:Component name="{comp}" type="application/x-fmu-sharedlibrary" '
            f'source="resources/{model}"><ssd:Connectors>{"".join(conns)}</ssd:Connectors>'
            f"{binding}</ssd:Component>")
    connections = []
    for se, sc, ee, ec in MASS_SPRING_CONNECTIONS:
        body = ""
        if transform is not None and (se, sc) == ("sub1", "x1"):
            factor, offset = transform
            body = f'<{transform_ns}:LinearTransformation factor="{factor!r}" offset="{offset!r}"/>'
        connections.append(f'<ssd:Connection startElement="{se}" startConnector="{sc}" '
                           f'endElement="{ee}" endConnector="{ec}">{body}</ssd:Connection>')
    experiment = ""
    if default_experiment is not None:
        experiment = (f'<ssd:DefaultExperiment startTime="{default_experiment[0]!r}" '
                      f'stopTime="{default_experiment[1]!r}"/>')

    def ns_attr(prefix: str, uri: str) -> str:
        return f'xmlns:{prefix}="{uri}"' if prefix else f'xmlns="{uri}"'

    ssd = ('<?xml version="1.0" encoding="UTF-8"?>\n'
           f'<ssd:SystemStructureDescription {ns_attr(d, SSD_NS)} {ns_attr(c, SSC_NS)} {ns_attr(v, SSV_NS)} '
           'version="1.0" name="MassSpring">'
           '<ssd:System name="MassSpring">'
           f'<ssd:Elements>{"".join(elements)}</ssd:Elements>'
           f'<ssd:Connections>{"".join(connections)}</ssd:Connections>'
           f"</ssd:System>{experiment}</ssd:SystemStructureDescription>\n")
    ssd = tag(ssd)
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for name, text in ssv_files.items():
            zf.writestr(name, tag(text))
        for model in MASS_SPRING_FMUS.values():
            zf.write(fmu_dir / model, f"resources/{model}")
    return path


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------

def _split_signal(signal: str) -> tuple[str, str]:
    comp, sep, var = signal.partition(".")
    if not sep or not comp or not var:
        raise ValueError(f"signal {signal!r} is not of the form 'component.variable'")
    return comp, var


def _n_steps(start: float, stop: float, step: float) -> int:
    n = round((stop - start) / step)
    if n < 1 or not math.isclose(start + n * step, stop, rel_tol=1e-9, abs_tol=1e-12):
        raise ValueError(f"(stop - start) = {stop - start!r} is not a whole number of steps of {step!r}")
    return n


def _structured(time: np.ndarray, columns: Mapping[str, np.ndarray]) -> np.ndarray:
    out = np.empty(len(time), dtype=[("time", "f8")] + [(name, "f8") for name in columns])
    out["time"] = time
    for name, values in columns.items():
        out[name] = values
    return out


# ---------------------------------------------------------------------------------------
# libcosim (libcosimpy 0.0.6, libcosim 0.11.2)
# ---------------------------------------------------------------------------------------

def _ns(seconds: float, what: str) -> int:
    ns = round(seconds * 1e9)
    if not math.isclose(ns, seconds * 1e9, rel_tol=0, abs_tol=1e-3):
        raise ValueError(f"{what} = {seconds!r} s is not a whole number of nanoseconds")
    return ns


def run_libcosim(
    ssp_path: str | Path,
    start: float,
    stop: float,
    step: float,
    signals: Sequence[str],
    *,
    observer: str = "time_series",
    log_level: str = "ERROR",
    timing: dict | None = None,
) -> np.ndarray:
    """Run an SSP archive (or a folder with ``SystemStructure.ssd``) in libcosim.

    Returns a structured array with ``time`` and one float column per signal
    ``"component.variable"`` (component = SSD Component name, variable = FMU variable
    name; any Real variable can be observed, not only SSD connectors), one row per
    communication point t_k = start + k*step, k = 0..n, n = (stop-start)/step.

    Semantics observed (MassSpring test system, h = 1 ms, see docs/peers.md):

    - Algorithm: fixed-step Jacobi.  Before the first step libcosim runs setup, then
      N+F zero-time get/set iterations in initialization mode (N simulators, F functions),
      then exitInitializationMode: the *initial output of a connected FMU is propagated to
      the connected input* (including a LinearTransformation) before the first doStep.
    - Row k=0 (time = start) holds the values after initialization (time-series
      observer's "simulation_initialized" sample); row k holds what the FMU returns after
      the k-th doStep, i.e. outputs at t_k.  Time stamps are libcosim's integer
      nanoseconds / 1e9, exactly start + k*step for steps that are whole nanoseconds.
    - An *input* observed at row k is the value the FMU held during step k (the value
      transferred after step k-1); the transfer made after step k only shows at row k+1.
      Only row 0 shows the propagated initial value.
    - ParameterBindings of a Component are applied (inline ssd:ParameterValues and
      source="x.ssv", relative to the .ssd); only variables of causality parameter or
      input are accepted, others are skipped with a logged warning; only the first
      binding of a component is used.  ssc:LinearTransformation factor/offset is applied.
    - ``start``: passed explicitly to libcosim (overrides DefaultExperiment/startTime).
      The step must be a whole number of nanoseconds (libcosim time is int64 ns).
    - The FMUs get t_k = ns_k / 1e9 and h_k = t_{k+1} - t_k (as doubles).

    Experiment (write_mass_spring_ssp, h = 1 ms; run_libcosim(ssp, 0, 0.003, 1e-3, ...)):
    sub1.x1 = 0, 0.001, 0.002001 and sub1.v1 = 1, 1.001, ...: v1' = -k1*x1 + k2*(x2-x1)
    was 1 on step 1, so sub1 saw x2 = sub2.x2(0) = 1.  With a LinearTransformation
    factor=2 offset=0.5 on sub1.x1 -> sub2.x1 (transform=(2.0, 0.5)): sub2.x1 =
    0.5, 0.5, 0.502, 0.504002 (row k = 2*sub1.x1[k-1] + 0.5, row 0 = 2*0 + 0.5) and
    sub2.v2[1] = -0.0015 = h*(-x2 + (0.5 - x2)): the transformed initial value drove step
    1.  params={"sub1": {"k1": 4.0}, "sub2": {"m2": 2.0}} (inline or .ssv) gave the same
    result as setting these inputs before initialization in benchmarks/floor.py.

    ``observer="time_series"`` (default) records every step in libcosim's buffered
    time-series observer and reads all samples at the end (``execution.step(n)`` runs the
    whole loop in C++).  ``observer="last_value"`` polls the last-value observer after
    each single ``execution.step()`` from Python; both give identical values (checked in
    tests/peers/test_peers_smoke.py).  The last-value observer returns zeros before the first
    step (libcosim initializes lazily inside the first ``step()``), so row 0 always comes
    from the time series.

    ``timing``: if a dict is given, ``timing["loop_seconds"]`` receives the wall time of
    the stepping alone (initialization included, since libcosim does it in the first step;
    loading, unzipping and reading the samples excluded).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy._internal import get_last_error_message, libcosimc, wrap_function

    # libcosimc logs every FMI call at TRACE level to stdout unless told otherwise
    log_output_level(getattr(CosimLogLevel, log_level))
    n = _n_steps(start, stop, step)
    step_ns, start_ns = _ns(step, "step"), _ns(start, "start")

    # CosimExecution.from_ssp_file() never passes a start time (start_time_defined=False)
    # and truncates the step with int(); call the C function directly.
    create = wrap_function(lib=libcosimc(), funcname="cosim_ssp_fixed_step_execution_create",
                           argtypes=[ctypes.c_char_p, ctypes.c_bool, ctypes.c_int64, ctypes.c_int64],
                           restype=ctypes.POINTER(CosimExecution))
    ptr = create(str(Path(ssp_path).resolve()).encode(), True, start_ns, step_ns)
    if not ptr:
        raise RuntimeError(f"libcosim could not load {ssp_path}: {get_last_error_message()}")
    execution = CosimExecution(CosimExecution._CosimExecution__create_key, ptr)

    slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
    refs: list[tuple[int, int]] = []
    for signal in signals:
        comp, var = _split_signal(signal)
        if comp not in slaves:
            raise KeyError(f"{signal}: no component {comp!r} in libcosim execution ({sorted(slaves)})")
        found = [v for v in execution.slave_variables(slaves[comp]) if v.name.decode() == var]
        if not found or found[0].type != CosimVariableType.REAL.value:
            raise KeyError(f"{signal}: no Real variable {var!r} in component {comp!r}")
        refs.append((slaves[comp], found[0].reference))

    series = CosimObserver.create_time_series(buffer_size=n + 1)  # default buffer: 10000 samples
    execution.add_observer(series)
    for index, vr in refs:
        if not series.start_time_series(index, vr, CosimVariableType.REAL):
            raise RuntimeError(f"libcosim: cannot observe {index}:{vr}: {get_last_error_message()}")

    columns: dict[str, np.ndarray] = {}
    t0 = _time.perf_counter()
    if observer == "time_series":
        if not execution.step(n):
            raise RuntimeError(f"libcosim step failed: {get_last_error_message()}")
    elif observer == "last_value":
        last = CosimObserver.create_last_value()
        execution.add_observer(last)
        polled = np.empty((n, len(refs)))
        by_slave: dict[int, list[int]] = {}
        for j, (index, vr) in enumerate(refs):
            by_slave.setdefault(index, []).append(j)
        for k in range(n):
            if not execution.step():
                raise RuntimeError(f"libcosim step failed: {get_last_error_message()}")
            for index, js in by_slave.items():
                polled[k, js] = last.last_real_values(index, [refs[j][1] for j in js])
    else:
        raise ValueError(f"observer must be 'time_series' or 'last_value', not {observer!r}")
    if timing is not None:
        timing["loop_seconds"] = _time.perf_counter() - t0

    # libcosimpy's time_series_real_samples() drops one sample per step number 0 (it
    # trims by counting zeros), so read the samples with the C function directly.
    get_samples = wrap_function(
        lib=libcosimc(), funcname="cosim_observer_slave_get_real_samples",
        argtypes=[ctypes.POINTER(CosimObserver), ctypes.c_int, ctypes.c_uint32, ctypes.c_int64,
                  ctypes.c_size_t, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int64),
                  ctypes.POINTER(ctypes.c_int64)],
        restype=ctypes.c_int64)
    time = None
    for j, (signal, (index, vr)) in enumerate(zip(signals, refs)):
        values = np.empty(n + 1)
        steps = np.empty(n + 1, dtype=np.int64)
        times = np.empty(n + 1, dtype=np.int64)
        got = get_samples(series.ptr(), index, vr, 0, n + 1,
                          values.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                          steps.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                          times.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)))
        if got != n + 1 or not np.array_equal(steps, np.arange(n + 1)):
            raise RuntimeError(f"libcosim returned {got} samples for {signal}, expected {n + 1}")
        if time is None:
            time = times / 1e9
        if observer == "last_value":
            values[1:] = polled[:, j]
        columns[signal] = values
    if time is None:
        time = start + step * np.arange(n + 1)
    return _structured(time, columns)


# ---------------------------------------------------------------------------------------
# fmpy.ssp (fmpy 0.3.32)
# ---------------------------------------------------------------------------------------

def run_fmpy_ssp(
    ssp_path: str | Path,
    start: float,
    stop: float,
    step: float,
    signals: Sequence[str],
    *,
    timing: dict | None = None,
) -> np.ndarray:
    """Run an SSP archive with ``fmpy.ssp.simulation.simulate_ssp`` (fmpy 0.3.32).

    Returns a structured array with ``time`` and one column per ``"component.connector"``
    signal, exactly as fmpy produced it (no re-stamping, no added initial row).

    Semantics observed (MassSpring test system, h = 1 ms, see docs/peers.md):

    - ``simulate_ssp`` returns a NumPy structured array: ``time`` plus one column per SSD
      Connector, named ``"<Component>.<connector>"`` (system connectors: bare name).
      Only SSD connectors are available: inputs are set and outputs read one variable per
      call, nothing else of the FMUs is observable.
    - Jacobi: every component steps with the connector values of the previous step, then
      all connections are copied.  *Every connector starts at 0.0* and FMU outputs are not
      read after initialization, so on the first step every connected input gets 0.0,
      not the connected output's initial value nor the FMU's start value.
    - Row k (k = 0..n-1) is stamped with the *start* time t_k of the step but holds the
      values after that step (outputs at t_k + h, inputs as copied after the step, i.e.
      equal to their source output at t_k + h).  There is no row for the initial point.
      Rows are produced by ``while time < stop: ...; time += step``: time stamps carry
      the accumulated rounding error, and 0..10 s by 1 ms gives 10001 rows (one step
      past stop).  Here stop - step/2 is passed as stop_time so exactly n rows come out.
    - SSD ParameterBindings are parsed (inline and .ssv) but never applied; only
      simulate_ssp's own ``parameter_set`` argument is (not used here).
      ssc:LinearTransformation is ignored (fmpy looks for ``ssd:LinearTransformation``,
      which the SSP 1.0 schema rejects, and never applies it either).
      DefaultExperiment is ignored (start/stop/step come from the arguments).
    - The SSD is validated against the SSP 1.0 XSD; an invalid SSD is rejected.
    - An SSD input connector that no connection drives is silently wired to the source
      of the previous input of the same loop (or raises UnboundLocalError if it is the
      first): declare only connected inputs.

    Experiment (write_mass_spring_ssp, h = 1 ms; run_fmpy_ssp(ssp, 0, 0.003, 1e-3, ...)):
    row 0 is stamped 0.0 and holds sub1.x1 = 0.001, sub1.v1 = 1.0, sub1.x2 = 1.0,
    sub2.v2 = -0.002: v1 stayed 1 because x1 = 0 and the x2 given to sub1 was 0.0
    (libcosim: v1 = 1.001 at t = 0.001); sub1.x2 = 1.0 is sub2.x2 after the step.  The
    rows equal benchmarks/floor.py with initial_inputs="zero", shifted by one row.
    With params (inline or .ssv) or transform=(2.0, 0.5) the result did not change.

    ``timing``: if a dict is given, ``timing["loop_seconds"]`` receives the wall time from
    the first to the end of the last ``do_step`` call (found by wrapping
    ``fmpy.ssp.simulation.do_step`` for the duration of the call).
    """
    import fmpy.ssp.simulation as fmpy_ssp
    from fmpy.ssp.simulation import simulate_ssp

    n = _n_steps(start, stop, step)
    # simulate_ssp loops `while time < stop_time: ...; time += step_size`; with the
    # accumulated rounding error 0..10 s by 1 ms gives 10001 rows.  Half a step less
    # as stop_time gives exactly n steps (stop_time is not used otherwise for FMI 2.0).
    original = fmpy_ssp.do_step
    stamps: list[float] = []
    if timing is not None:
        def do_step(*args, **kwargs):
            if not stamps:
                stamps.append(_time.perf_counter())
            original(*args, **kwargs)
            stamps[1:] = [_time.perf_counter()]
        fmpy_ssp.do_step = do_step
    try:
        result = simulate_ssp(str(ssp_path), start_time=start, stop_time=stop - 0.5 * step, step_size=step)
    finally:
        fmpy_ssp.do_step = original
    if timing is not None:
        timing["loop_seconds"] = stamps[-1] - stamps[0]
    if len(result) != n:
        raise RuntimeError(f"fmpy.ssp produced {len(result)} rows for {n} steps")
    missing = [s for s in signals if s not in result.dtype.names]
    if missing:
        raise KeyError(f"fmpy.ssp has no column(s) {missing}; it records SSD connectors only: "
                       f"{list(result.dtype.names)}")
    return _structured(result["time"], {s: result[s] for s in signals})
