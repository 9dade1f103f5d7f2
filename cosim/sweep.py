"""Parameter sweeps: every combination of swept values and seeds, run in parallel, one results table.

A sweep takes a scenario and, for some parameters ``component.variable``, a list of values;
it runs the Cartesian product of those lists (times the seeds, when given) and writes

- ``OUTPUT/runs/<id>.csv`` and ``<id>.json``: each run's results and metadata, exactly as
  ``cosim run`` writes them, and ``<id>.ssv``: the run's parameter values as an SSP 1.0
  parameter set, so ``cosim run SCENARIO --param-set OUTPUT/runs/<id>.ssv`` repeats it;
- ``OUTPUT/sweep.csv`` and ``OUTPUT/sweep.parquet``: one row per run (id, swept values, seed,
  status, message, wall time, the requested step metrics), rewritten as runs finish, so a
  sweep stopped halfway keeps every finished row.

The run id is a hash of everything that decides the result: the scenario's files, every
FMU's GUID and file contents, the parameter sets, the swept values, the seed and the time
grid.  A rerun skips every run whose id has a finished row (completed or discarded) and
its result files; change anything and the id changes.

Values go in the way ``--param-set`` values do (SSP 1.0 parameter precedence: applied
last, beating component- and system-level bindings), and every name and value is checked
by the master's own validation (`cosim.graph.build_plan`) before the first run starts.
Runs go to a local process pool (``spawn`` start method: FMUs loaded in the parent are
never forked), run serially in this process, or go to a Dask distributed cluster; Dask
workers must see the scenario and the output folder at the same paths.
"""
from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import multiprocessing
import os
import re
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np

from .errors import CosimError, SetupError, did_you_mean
from .fmu import exchange_type
from .graph import build_plan, split_system_name
from .metrics import METRICS, step_response
from .safeio import max_unpacked_bytes, unpack_limit
from .simulation import Prepared, prepare, run
from .ssp import NS, ParameterValue

Value = float | int | bool | str
#: Arrow type of a swept column per FMI variable type
_ARROW_TYPES = {"Real": "float64", "Integer": "int64", "Boolean": "bool", "String": "string"}
_RANGE = re.compile(r"^\s*([-+0-9.eE]+)\s*:\s*([-+0-9.eE]+)\s*:\s*(\d+)\s*$")
#: Statuses whose results are kept and not run again
FINISHED = ("completed", "discarded")
SOURCE = "cosim sweep --set"


@dataclass(frozen=True)
class Metric:
    """Step metrics of ``signal`` following ``setpoint`` (see `cosim.metrics.step_metrics`)."""
    signal: str
    setpoint: str

    def columns(self) -> list[str]:
        return [f"{self.signal}:{m}" for m in METRICS]

    def reason_column(self) -> str:
        """The column saying why a metric of this signal is undefined (`cosim.metrics.Response.reasons`)."""
        return f"undefined({self.signal})"


@dataclass(frozen=True)
class Task:
    """One run as a worker process receives it (plain data, picklable)."""
    run_id: str
    scenario: str
    parameter_sets: tuple[str, ...]
    fmu_dirs: tuple[str, ...]
    start: float
    stop: float
    step: float
    algorithm: str
    csv: str
    metrics: tuple[Metric, ...]
    #: the parent's limit on what an .ssp archive may expand to (--max-unpacked), in bytes
    max_unpacked: int


@dataclass
class SweepResult:
    """The table's rows in combination order, and how many runs were run or skipped."""
    rows: list[dict[str, Any]]
    ran: int
    skipped: int
    csv: Path
    parquet: Path
    columns: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if r["status"] == "failed"]


# --------------------------------------------------------------------------- arguments

def parse_set(text: str) -> tuple[str, list[str]]:
    """``comp.var=v1,v2,...`` (each item may be a range ``start:stop:count``) -> name, items."""
    name, sep, values = text.partition("=")
    if not sep or not name.strip() or not values.strip():
        raise SetupError(f"'{text}' is not NAME=VALUE[,VALUE...] (e.g. controller.Kc=2,4,8 or "
                         "controller.Kc=2:8:4 for 4 values from 2 to 8).", element="--set")
    return name.strip(), [v.strip() for v in values.split(",")]


def parse_seeds(text: str) -> list[int]:
    """``1..20`` (inclusive) or ``1,5,9`` -> the seeds."""
    try:
        if ".." in text:
            first, last = (int(x) for x in text.split(".."))
            if last < first:
                raise ValueError
            return list(range(first, last + 1))
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise SetupError(f"'{text}' is not a list of seeds: give FIRST..LAST (e.g. 1..20) or "
                         "integers separated by commas.", element="--seeds") from None


def parse_metric(text: str | Metric | tuple[str, str]) -> Metric:
    """``SIGNAL:SETPOINT`` (e.g. plant.y:setpoint.y) -> Metric."""
    if isinstance(text, Metric):
        return text
    if isinstance(text, tuple):
        return Metric(*text)
    signal, sep, setpoint = text.partition(":")
    if not sep or not signal or not setpoint:
        raise SetupError(f"'{text}' is not SIGNAL:SETPOINT (e.g. plant.y:setpoint.y).", element="--metrics")
    return Metric(signal, setpoint)


def _typed(raw: Value, var_type: str, name: str) -> list[Value]:
    """A --set item as values of the FMU variable's type; a range item gives several."""
    where = {"element": "--set", "variable": name}
    if isinstance(raw, str) and var_type in ("Real", "Integer") and (m := _RANGE.match(raw)):
        start, stop, count = float(m[1]), float(m[2]), int(m[3])
        points = np.linspace(start, stop, count)
        if var_type == "Integer":
            if not all(float(p).is_integer() for p in points):
                raise SetupError(f"the range {raw} does not fall on integers; {name} is an Integer.", **where)
            return [int(p) for p in points]
        return [float(p) for p in points]
    try:
        if var_type == "Real" and not isinstance(raw, bool):
            return [float(raw)]
        if var_type == "Integer" and not isinstance(raw, bool):
            number = float(raw)
            if number.is_integer():
                return [int(number)]
        elif var_type == "Boolean":
            if isinstance(raw, bool):
                return [raw]
            if str(raw).lower() in ("true", "1", "false", "0"):
                return [str(raw).lower() in ("true", "1")]
        elif var_type == "String":
            return [str(raw)]
    except ValueError:
        pass
    raise SetupError(f"'{raw}' is not a {var_type} value, which the FMU declares for this variable.", **where)


# --------------------------------------------------------------------------- planning

@dataclass
class _Run:
    index: int
    run_id: str
    values: dict[str, Value]
    seed: int | None
    parameters: list[ParameterValue]


def _variable(prepared: Prepared, name: str):
    """The FMU variable behind ``comp.var``, or the master's own message for an unknown name."""
    p = ParameterValue(name, "Real", 0.0, SOURCE, 0)
    comp, var = split_system_name(prepared.plan.structure, p)
    return prepared.plan.fmus[comp].variable(var, f"--set {name}", SOURCE)


def _seed_parameters(prepared: Prepared, named: Sequence[str]) -> list[str]:
    if named:
        return list(named)
    found = [f"{comp}.seed" for comp, desc in prepared.plan.fmus.items()
             if "seed" in desc.variables and desc.variables["seed"].causality == "parameter"]
    if not found:
        raise SetupError("--seeds given, but no component of the scenario has a parameter named 'seed'; "
                         "name the parameter to set with --seed-parameter COMPONENT.VARIABLE.",
                         file=str(prepared.plan.structure.ssd_file), element="--seeds")
    return found


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _identity(prepared: Prepared, parameter_sets: Sequence[Path]) -> dict:
    """Everything outside the swept values that decides a run's result."""
    structure = prepared.plan.structure
    if structure.archive is not None:
        files = {structure.archive.name: _digest(structure.archive)}
    else:
        files = {p.name: _digest(p) for p in sorted(structure.base_dir.iterdir())
                 if p.suffix.lower() in (".ssd", ".ssv") and p.is_file()}
    grid = prepared.grid
    return {"scenario": files,
            "fmus": {name: [d.md.guid, _digest(d.path)] for name, d in prepared.plan.fmus.items()},
            "parameter_sets": [_digest(Path(p)) for p in parameter_sets],
            "grid": [grid.start, grid.stop, grid.step], "algorithm": prepared.algorithm}


def _run_id(identity: dict, parameters: list[ParameterValue]) -> str:
    key = json.dumps({**identity, "parameters": [[p.name, p.type, p.value] for p in parameters]},
                     sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def _plan_runs(prepared: Prepared, sets: Mapping[str, Sequence[Value]], seeds: Sequence[int],
               seed_parameters: Sequence[str], identity: dict) -> tuple[list[_Run], dict[str, str]]:
    """Type every value, check every name and value with the master's validation, and list the runs."""
    types: dict[str, str] = {}
    typed: dict[str, list[Value]] = {}
    for name, raw_values in sets.items():
        if not raw_values:
            raise SetupError("no values given.", element="--set", variable=name)
        types[name] = exchange_type(_variable(prepared, name))
        typed[name] = list(dict.fromkeys(v for raw in raw_values for v in _typed(raw, types[name], name)))
    seed_names = _seed_parameters(prepared, seed_parameters) if seeds else []
    for name in seed_names:
        types[name] = exchange_type(_variable(prepared, name))
    overlap = set(seed_names) & set(sets)
    if overlap:
        raise SetupError(f"{', '.join(sorted(overlap))} is both swept with --set and set by --seeds.",
                         element="--set")
    every = [ParameterValue(name, types[name], v, SOURCE, 0) for name, vs in typed.items() for v in vs]
    every += [ParameterValue(name, types[name], _typed(s, types[name], name)[0], "cosim sweep --seeds", 0)
              for name in seed_names for s in seeds]
    build_plan(prepared.plan.structure, every)      # the master's messages for names, types, ranges
    runs = []
    for index, combo in enumerate(product(*typed.values(), *([seeds] if seeds else []))):
        values = dict(zip(typed, combo))
        seed = combo[-1] if seeds else None
        parameters = [ParameterValue(n, types[n], v, SOURCE, 0) for n, v in values.items()]
        parameters += [ParameterValue(n, types[n], _typed(seed, types[n], n)[0], SOURCE, 0) for n in seed_names]
        runs.append(_Run(index, _run_id(identity, parameters), values, seed, parameters))
    return runs, types


def _check_metrics(prepared: Prepared, metrics: Sequence[Metric]) -> None:
    outputs, inputs = prepared.plan.recorded()
    names = outputs + inputs
    for m in metrics:
        for name in (m.signal, m.setpoint):
            if name not in names:
                raise SetupError(f"no recorded signal '{name}' (signals are the components' connectors).",
                                 element="--metrics", variable=name, hint=did_you_mean(name, names))


def write_ssv(path: Path, parameters: Iterable[ParameterValue], name: str) -> None:
    """An SSP 1.0 parameter set (SystemStructureParameterValues.xsd) holding ``parameters``."""
    from lxml import etree

    ssv = NS["ssv"]
    root = etree.Element(f"{{{ssv}}}ParameterSet", nsmap={"ssv": ssv}, version="1.0", name=name)
    container = etree.SubElement(root, f"{{{ssv}}}Parameters")
    for p in parameters:
        element = etree.SubElement(container, f"{{{ssv}}}Parameter", name=p.name)
        text = str(p.value).lower() if isinstance(p.value, bool) else (repr(p.value) if isinstance(p.value, float)
                                                                          else str(p.value))
        etree.SubElement(element, f"{{{ssv}}}{p.type}", value=text)
    path.write_bytes(etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))


# --------------------------------------------------------------------------- one run (in a worker)

def execute(task: Task) -> dict[str, Any]:
    """Run one combination (in a worker process) and return its table row (without the swept values)."""
    began = time.perf_counter()
    row: dict[str, Any] = {"run_id": task.run_id, "status": "completed", "message": None}
    result = None
    try:
        with unpack_limit(task.max_unpacked):  # the FMUs are unpacked by run(): inside the limit too
            prepared = prepare(task.scenario, start_time=task.start, stop_time=task.stop, step_size=task.step,
                               algorithm=task.algorithm, parameter_sets=task.parameter_sets,
                               fmu_dirs=task.fmu_dirs)
            try:
                result, metadata = run(prepared, output=task.csv)
            finally:
                prepared.close()
        if metadata["status"] == "discarded":
            row.update(status="discarded", message=metadata["message"])
    except CosimError as e:
        row.update(status="failed", message=str(e))
    row["wall_time"] = time.perf_counter() - began
    row.update(_metrics(result, task.metrics))
    return row


def _metrics(result: np.ndarray | None, metrics: Sequence[Metric]) -> dict[str, float | str | None]:
    out: dict[str, float | None] = {}
    for m in metrics:
        response = (step_response(result["time"], result[m.signal], result[m.setpoint])
                    if result is not None and len(result) else None)
        values = response.values if response is not None else {}
        out.update({f"{m.signal}:{k}": float(values[k]) if k in values else None for k in METRICS})
        out[m.reason_column()] = response.reasons() if response is not None else "the run produced no samples"
    return out


# --------------------------------------------------------------------------- the table

def _schema(swept: Mapping[str, str], seeded: bool, metrics: Sequence[Metric]):
    import pyarrow as pa

    fields = [("run_id", pa.string())]
    fields += [(name, pa.type_for_alias(_ARROW_TYPES[t])) for name, t in swept.items()]
    fields += [("seed", pa.int64())] if seeded else []
    fields += [("status", pa.string()), ("message", pa.string()), ("wall_time", pa.float64())]
    fields += [(c, pa.float64()) for m in metrics for c in m.columns()]
    fields += [(m.reason_column(), pa.string()) for m in metrics]
    return pa.schema(fields)


def _write_table(rows: list[dict[str, Any]], schema, csv: Path, parquet: Path) -> None:
    """Both files replaced atomically, so a reader or a crash never sees half a table."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=schema)
    for path, write in ((parquet, pq.write_table), (csv, pacsv.write_csv)):
        tmp = path.with_name(path.name + ".tmp")
        write(table, tmp)
        os.replace(tmp, path)


def read_table(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a sweep table (``sweep.parquet``, typed)."""
    import pyarrow.parquet as pq
    return pq.read_table(path).to_pylist()


def _finished_before(output: Path, runs_dir: Path) -> dict[str, dict[str, Any]]:
    """Rows of an earlier sweep into this folder whose results are still on disk."""
    parquet = output / "sweep.parquet"
    if not parquet.is_file():
        return {}
    try:
        rows = read_table(parquet)
    except Exception as e:  # noqa: BLE001 -- pyarrow raises several types for a damaged file
        raise SetupError(f"cannot read the earlier sweep table ({e}); delete it or pass --force.",
                         file=str(parquet)) from None
    return {r["run_id"]: r for r in rows if r.get("status") in FINISHED
            and (runs_dir / f"{r['run_id']}.csv").is_file() and (runs_dir / f"{r['run_id']}.json").is_file()}


# --------------------------------------------------------------------------- dispatch

Executor = str | cf.Executor | Any   # "process", "serial", a Dask scheduler address, "local:N", or a Client


def _dispatch(tasks: list[Task], executor: Executor, workers: int | None,
              done: Callable[[Task, dict[str, Any]], None]) -> None:
    """Hand the runs to the chosen engine; ``done`` is called in this process as each finishes."""
    if not tasks:
        return
    if executor == "serial":
        for task in tasks:
            try:
                row = execute(task)
            except Exception as e:  # noqa: BLE001 -- as in a worker: a failed row, not a stopped sweep
                row = _failed(task, e)
            done(task, row)
    elif executor == "process":
        context = multiprocessing.get_context("spawn")
        pool = cf.ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, mp_context=context)
        try:
            _collect(tasks, pool, cf.as_completed, done)
        finally:             # on Ctrl-C, runs not started yet are dropped instead of awaited
            pool.shutdown(wait=True, cancel_futures=True)
    elif isinstance(executor, cf.Executor):
        _collect(tasks, executor, cf.as_completed, done)
    else:
        Client, LocalCluster, as_completed = _distributed()

        if isinstance(executor, Client):
            _collect(tasks, executor, as_completed, done)
        elif isinstance(executor, str) and executor.startswith("local:"):
            n = _local_workers(executor)
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster, Client(cluster) as client:
                _collect(tasks, client, as_completed, done)
        elif isinstance(executor, str):
            try:
                client = Client(executor, timeout=10)
            except OSError as e:
                raise SetupError(f"cannot reach the Dask scheduler ({e}).", element="--scheduler",
                                 hint="Start one with 'dask scheduler' and workers with 'dask worker "
                                      "ADDRESS', or use --scheduler local:N.") from None
            with client:
                _collect(tasks, client, as_completed, done)
        else:
            raise SetupError(f"unknown executor {executor!r}: give 'process', 'serial', a Dask scheduler "
                             "address, 'local:N', a concurrent.futures.Executor or a distributed.Client.")


def _distributed():
    """Dask's distributed scheduler, an optional dependency (``pip install 'greyfmu[dask]'``)."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise SetupError("sweeps on a Dask cluster need Dask, which is not installed; install it with "
                         "pip install 'greyfmu[dask]' (or run on the local process pool: --workers N).",
                         element="--scheduler") from None
    return Client, LocalCluster, as_completed


def _local_workers(executor: str) -> int:
    """N of ``local:N`` (a Dask LocalCluster of N worker processes)."""
    n = executor.split(":", 1)[1]
    if not n.isdigit() or int(n) < 1:
        raise SetupError(f"'{executor}': give local:N with N the number of worker processes.",
                         element="--scheduler")
    return int(n)


def _collect(tasks: list[Task], engine, as_completed, done) -> None:
    """Submit every run; a worker that dies or raises makes that run a failed row, not a stopped sweep."""
    futures = {engine.submit(execute, task, **_dask_options(engine)): task for task in tasks}
    for future in as_completed(list(futures)):
        task = futures[future]
        try:
            row = future.result()
        except Exception as e:  # noqa: BLE001 -- a crashed worker process or a lost Dask worker
            row = _failed(task, e)
        done(task, row)


def _failed(task: Task, error: Exception) -> dict[str, Any]:
    return {"run_id": task.run_id, "status": "failed", "message": f"{type(error).__name__}: {error}",
            "wall_time": None, **_metrics(None, task.metrics)}


def _dask_options(engine) -> dict[str, Any]:
    """Dask caches results of equal calls ("pure"); a run writes files, so it is never pure."""
    return {} if isinstance(engine, cf.Executor) else {"pure": False}


# --------------------------------------------------------------------------- the sweep

def sweep(scenario: str | Path, sets: Mapping[str, Sequence[Value]], *, seeds: Sequence[int] = (),
          seed_parameters: Sequence[str] = (), metrics: Sequence[str | Metric | tuple[str, str]] = (),
          parameter_sets: Sequence[str | Path] = (), start_time: float | None = None,
          stop_time: float | None = None, step_size: float | None = None, algorithm: str | None = None,
          fmu_dirs: Sequence[str | Path] = (), output: str | Path = "results/sweep",
          executor: Executor = "process", workers: int | None = None, force: bool = False,
          progress: bool = False) -> SweepResult:
    """Run every combination of ``sets`` (name -> values, strings parsed by the variable's type)
    times ``seeds`` and write the results table (see the module docstring).

    Raises `SetupError` before any run for a bad name, value, seed parameter or metric; a run
    that fails is a row with status "failed" and its message.
    """
    output = Path(output)
    scenario = Path(scenario)
    if isinstance(executor, str) and executor.startswith("local:"):
        _local_workers(executor)
    metric_list = [parse_metric(m) for m in metrics]
    parameter_sets = [Path(p).resolve() for p in parameter_sets]
    prepared = prepare(scenario, start_time=start_time, stop_time=stop_time, step_size=step_size,
                       algorithm=algorithm, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs)
    try:       # this prepare also builds our FMUs once, before workers could race to build them
        _check_metrics(prepared, metric_list)
        identity = _identity(prepared, parameter_sets)
        runs, types = _plan_runs(prepared, sets, seeds, seed_parameters, identity)
        grid, algo = prepared.grid, prepared.algorithm
    finally:
        prepared.close()
    swept_types = {name: types[name] for name in sets}
    schema = _schema(swept_types, bool(seeds), metric_list)
    runs_dir = output / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    csv, parquet = output / "sweep.csv", output / "sweep.parquet"
    before = {} if force else _finished_before(output, runs_dir)

    rows: dict[int, dict[str, Any]] = {}          # finished rows by combination index
    fixed: dict[str, tuple[int, dict[str, Any]]] = {}   # run id -> index, swept values and seed
    tasks: list[Task] = []
    for r in runs:
        fixed[r.run_id] = (r.index, {**r.values, **({"seed": r.seed} if seeds else {})})
        if r.run_id in before:
            old = before[r.run_id]
            missing = [m for m in metric_list if any(c not in old for c in m.columns())]
            if missing:
                from .results import read
                old = {**old, **_metrics(read(runs_dir / f"{r.run_id}.csv"), missing)}
            rows[r.index] = {**old, **fixed[r.run_id][1]}
            continue
        ssv = runs_dir / f"{r.run_id}.ssv"
        write_ssv(ssv, r.parameters, name=f"sweep run {r.run_id}")
        tasks.append(Task(r.run_id, str(scenario.resolve()),
                          tuple(str(p) for p in [*parameter_sets, ssv.resolve()]),
                          tuple(str(Path(d).resolve()) for d in fmu_dirs), grid.start, grid.stop, grid.step,
                          algo, str((runs_dir / f"{r.run_id}.csv").resolve()), tuple(metric_list),
                          max_unpacked_bytes()[0]))
    skipped = len(runs) - len(tasks)

    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(runs), initial=skipped, unit="run", desc=f"sweep {scenario.name}", file=sys.stderr)

    def finished(task: Task, row: dict[str, Any]) -> None:
        index, values = fixed[task.run_id]
        rows[index] = {**row, **values}
        _write_table([rows[i] for i in sorted(rows)], schema, csv, parquet)
        if bar is not None:
            bar.update()

    _write_table([rows[i] for i in sorted(rows)], schema, csv, parquet)
    try:
        _dispatch(tasks, executor, workers, finished)
    finally:
        if bar is not None:
            bar.close()
    ordered = [{name: rows[i].get(name) for name in schema.names} for i in sorted(rows)]
    return SweepResult(ordered, ran=len(tasks), skipped=skipped, csv=csv, parquet=parquet, columns=schema.names)
