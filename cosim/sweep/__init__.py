"""Parameter sweeps: every combination of swept values and seeds, run in parallel, one results table.

A sweep takes a scenario and, for some parameters ``component.variable``, a list of values;
it runs the Cartesian product of those lists (times the seeds, when given) and writes

- ``OUTPUT/runs/<id>.csv`` and ``<id>.json``: each run's results and metadata, exactly as
  ``cosim run`` writes them, and ``<id>.ssv``: the run's parameter values as an SSP 1.0
  parameter set, so ``cosim run SCENARIO --param-set OUTPUT/runs/<id>.ssv`` repeats it
  (not with ``run_files=False``, ``--no-run-files``: the table only);
- ``OUTPUT/sweep.csv`` and, with pyarrow installed (the ``parquet`` extra), ``OUTPUT/sweep.parquet``:
  one row per run (id, swept values, seed, status, message, wall time, the requested step
  metrics), rewritten as runs finish (in batches, `.batch`), so a sweep stopped halfway keeps
  every finished row;
- ``OUTPUT/sweep.png`` (when metrics are asked for): each metric against each swept parameter,
  seeds and the other parameters as spread (`.figure`).

The sweep holds the locks of its two tables (``OUTPUT/sweep.csv.lock`` and
``OUTPUT/sweep.parquet.lock``, `cosim.safeio.lock_output`) while it runs, so a second sweep
or a `cosim run` writing either table is refused; every file is written as ``<name>.part``
and renamed into place.  ``OUTPUT`` must be a folder (or not exist yet) and must not hold a
run's results named ``sweep.*`` (`cosim.record.outputs.check_sweep_folder`).

The run id is a hash of everything that decides the result: the scenario's files, every
FMU's GUID and file contents, the parameter sets, the swept values, the seed and the time
grid.  A rerun skips every run whose id has a finished row (completed or discarded) and
its result files; change anything and the id changes.

Values go in the way ``--param-set`` values do (SSP 1.0 parameter precedence: applied
last, beating component- and system-level bindings), and every name and value is checked
by the master's own validation (`cosim.plan.parameters.check_values`) before the first run starts.
Runs go to a local process pool (``spawn`` start method: FMUs loaded in the parent are
never forked), run serially in this process, or go to a Dask distributed cluster whose
workers need only this package installed: the scenario is packed once and handed to them,
and each run's result files come back to this process (`.shipping`, `.cluster`).  Each worker
keeps the scenario and its FMU instances across its runs, reset between them (`.worker`,
`cosim.run.instances.reuse`; ``reuse=False``: every run afresh), with results identical to fresh runs.
"""
from __future__ import annotations

import hashlib
import json
import sys
import tempfile
import warnings
from collections.abc import Mapping, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import CosimError
from ..record.outputs import check_sweep_folder
from ..safeio import lock_output, max_unpacked_bytes
from ..model.grid import Grid
from ..plan.prepare import Prepared, Scenario, load_scenario, prepare_scenario
from ..present.plots import signal_units
from .batch import BatchedTable
from .cluster import check_scheduler, dispatch_cluster
from .dispatch import Executor, Task, dispatch, is_cluster, run_metrics
from .figure import summary_figure
from .shipping import package_of
from .table import finished_before, read_table, schema_of, write_table
from .values import (
    Metric,
    Value,
    check_metrics,
    identity_of,
    parse_metric,
    parse_seeds,
    parse_set,
    plan_runs,
    write_ssv,
)

__all__ = ["Metric", "SweepResult", "parse_metric", "parse_seeds", "parse_set", "read_table", "sweep", "write_ssv"]


@dataclass
class SweepResult:
    """The table's rows in combination order, and how many runs were run or skipped."""
    rows: list[dict[str, Any]]
    ran: int
    skipped: int
    csv: Path
    parquet: Path | None          # None without pyarrow (the ``parquet`` extra)
    columns: list[str] = field(default_factory=list)
    figure: Path | None = None

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if r["status"] == "failed"]



def _shipped_plan(loaded: Scenario, ssv: Path, start_values: Sequence[str], grid: Grid,
                  algorithm: str) -> Prepared | None:
    """One run's plan for a local worker (`Task.prepared`), prepared as the worker would
    (`cosim.sweep.worker.prepare_task`); None for a run whose plan is refused: the worker
    prepares it again and reports the refusal as that run's failed row."""
    try:
        with warnings.catch_warnings():   # the sweep's own plan has warned already
            warnings.simplefilter("ignore", RuntimeWarning)
            return prepare_scenario(loaded, parameter_sets=[ssv.resolve()], start_values=start_values,
                                    start_time=grid.start, stop_time=grid.stop, step_size=grid.step,
                                    algorithm=algorithm)
    except CosimError:
        return None


def sweep(scenario: str | Path, sets: Mapping[str, Sequence[Value]], *, seeds: Sequence[int] = (),
          seed_parameters: Sequence[str] = (), metrics: Sequence[str | Metric | tuple[str, str]] = (),
          parameter_sets: Sequence[str | Path] = (), start_time: float | None = None,
          stop_time: float | None = None, step_size: float | None = None, algorithm: str | None = None,
          fmu_dirs: Sequence[str | Path] = (), start_values: Sequence[str] = (),
          input_file: str | Path | None = None, output: str | Path = "results/sweep",
          executor: Executor = "process", workers: int | None = None, force: bool = False,
          progress: bool = False, run_files: bool = True, reuse: bool = True) -> SweepResult:
    """Run every combination of ``sets`` (name -> values, strings parsed by the variable's type)
    times ``seeds`` and write the results table (see the module docstring).  ``start_values``
    (``component.variable=value``) and ``input_file`` (an input table) apply to every run as
    `cosim run`'s --start-value and --input-file do (`cosim.plan.prepare.prepare`).
    ``run_files``: write each run's ``runs/<id>.csv``, ``.json`` and ``.ssv`` (False: the table
    only, and a rerun reruns every run); ``reuse``: each worker keeps the scenario and the FMU
    instances across its runs (`cosim.sweep.worker`; False: every run read and instantiated afresh).

    Raises `SetupError` before any run for a bad name, value, seed parameter or metric; a run
    that fails is a row with status "failed" and its message.
    """
    output = check_sweep_folder(Path(output))
    scenario = Path(scenario)
    check_scheduler(executor)
    metric_list = [parse_metric(m) for m in metrics]
    parameter_sets = [Path(p).resolve() for p in parameter_sets]
    inputs = None if input_file is None else Path(input_file).resolve()
    fmu_dirs = [Path(d).resolve() for d in fmu_dirs]
    # the scenario read once here, kept (an .ssp's extraction folder with it) until the runs are done:
    # each run's plan is prepared from it and shipped with its task to a local worker
    loaded = load_scenario(scenario.resolve(), parameter_sets=parameter_sets, fmu_dirs=fmu_dirs,
                           input_file=inputs)
    try:       # this prepare also builds our FMUs once, before workers could race to build them
        prepared = prepare_scenario(loaded, start_time=start_time, stop_time=stop_time, step_size=step_size,
                                    algorithm=algorithm, start_values=start_values)
        check_metrics(prepared, metric_list)
        identity = identity_of(prepared, parameter_sets, start_values, inputs)
        runs, types = plan_runs(prepared, sets, seeds, seed_parameters, identity)
        grid, algo = prepared.grid, prepared.algorithm
        package = package_of(prepared) if is_cluster(executor) else None
        units = signal_units(prepared.plan)
        sweep_key = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
        swept_types = {name: types[name] for name in sets}
        schema = schema_of(swept_types, bool(seeds), metric_list)
    except BaseException:
        loaded.close()
        raise
    csv, parquet = output / "sweep.csv", output / "sweep.parquet"
    runs_dir = output / "runs"
    with ExitStack() as locks:   # the locks a run writing either table takes: one writer per folder
        locks.enter_context(loaded)
        for table in (csv, parquet):
            locks.enter_context(lock_output(table))
        if run_files:
            runs_dir.mkdir(parents=True, exist_ok=True)
        else:   # the runs' parameter sets only for the workers to read, removed after the sweep
            output.mkdir(parents=True, exist_ok=True)
            sets_dir = Path(locks.enter_context(tempfile.TemporaryDirectory(prefix="cosim-sweep-sets-")))
        before = {} if force or not run_files else finished_before(output, runs_dir, schema)

        rows: dict[int, dict[str, Any]] = {}          # finished rows by combination index
        fixed: dict[str, tuple[int, dict[str, Any]]] = {}   # run id -> index, swept values and seed
        tasks: list[Task] = []
        for r in runs:
            fixed[r.run_id] = (r.index, {**r.values, **({"seed": r.seed} if seeds else {})})
            if r.run_id in before:
                old = before[r.run_id]
                missing = [m for m in metric_list if any(c not in old for c in m.columns())]
                if missing:
                    from ..record.results import read
                    old = {**old, **run_metrics(read(runs_dir / f"{r.run_id}.csv"), missing)}
                rows[r.index] = {**old, **fixed[r.run_id][1]}
                continue
            ssv = (runs_dir if run_files else sets_dir) / f"{r.run_id}.ssv"
            write_ssv(ssv, r.parameters, name=f"sweep run {r.run_id}")
            shipped = _shipped_plan(loaded, ssv, start_values, grid, algo) if reuse and package is None else None
            tasks.append(Task(r.run_id, str(scenario.resolve()),
                              tuple(str(p) for p in [*parameter_sets, ssv.resolve()]),
                              tuple(str(Path(d).resolve()) for d in fmu_dirs), grid.start, grid.stop, grid.step,
                              algo, str((runs_dir / f"{r.run_id}.csv").resolve()), tuple(metric_list),
                              max_unpacked_bytes()[0], tuple(start_values),
                              None if inputs is None else str(inputs), shared_sets=len(parameter_sets),
                              sweep_key=sweep_key, reuse=reuse, run_files=run_files, prepared=shipped))
        skipped = len(runs) - len(tasks)

        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=len(runs), initial=skipped, unit="run", desc=f"sweep {scenario.name}", file=sys.stderr)

        table = BatchedTable(rows, lambda ordered: write_table(ordered, schema, csv, parquet))

        def finished(task: Task, row: dict[str, Any]) -> None:
            index, values = fixed[task.run_id]
            table.add(index, {**row, **values})
            if bar is not None:
                bar.update()

        write_table([rows[i] for i in sorted(rows)], schema, csv, parquet)
        try:
            if package is not None:
                dispatch_cluster(tasks, executor, package, finished)
            else:
                dispatch(tasks, executor, workers, finished)
        finally:
            table.close()
            if bar is not None:
                bar.close()
        ordered = [{name: rows[i].get(name) for name in schema.names} for i in sorted(rows)]
        figure = summary_figure(ordered, list(sets) or (["seed"] if seeds else []),
                                [c for m in metric_list for c in m.columns()], output / "sweep.png", scenario.name,
                                {name: unit for name, (unit, _) in units.items()})
        return SweepResult(ordered, ran=len(tasks), skipped=skipped, csv=csv,
                           parquet=parquet if parquet.is_file() else None, columns=schema.names,
                           figure=figure)
