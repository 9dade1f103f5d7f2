"""``cosim tune``: search the parameters of any components of a scenario (a controller FMU of
ours, a third party's plant FMU) that minimise a control-loop objective under constraints,
with SciPy's optimisers over parallel co-simulations on the sweep's machinery.

    cosim tune ssp/pid_fopdt --param controller.Kc=0.5:50:log --param controller.Ti=1:100:log \\
        --objective ITAE:plant.y --constraint "overshoot:plant.y<=10%" --workers 2

Each evaluation of a point is one co-simulation per noise seed (``seeds``), run on the engines
of ``cosim sweep`` (a local process pool, this process, or Dask) kept open for the whole
tuning, each worker keeping its scenario and its FMU instances (`cosim.tune.engines`);
objective terms and constraints are measured in the worker (`cosim.tune.measures`), averaged
over the seeds (a constraint: its worst seed).  A run that fails, or kills its worker, makes
its evaluation "failed" with the error in the table, +inf to the optimiser, and the tuning
goes on.  The optimisers are SciPy's (`cosim.tune.optimizers`): differential evolution by
default, a generation to a batch; Nelder–Mead for a local search.

``OUTPUT`` (default ``results/<name>_tune``) gets

- ``tune.csv`` (and ``tune.parquet`` with pyarrow): one row per evaluation, in order: its
  number and batch, the parameter values, status, error and message, the objective, each
  term and constraint, the violation, feasible, the best objective so far and the runs'
  seconds; written as evaluations finish;
- ``tune.json``: the settings (and the digest of what decides a row) and the result;
- ``best.ssv``: the best parameters, for ``cosim run SCENARIO --param-set OUTPUT/best.ssv``
  (with the same ``--param-set`` files and start values the tuning had);
- ``best.csv``/``best.json``: the best point run again (its first seed), ``convergence.png``
  and ``tune.html``: the tuning's summary, the convergence plot, then the best run's report.

A tuning stopped half way (Ctrl-C, a crash) is resumed by the same command: the optimiser is
replayed from its seed and every point already in ``tune.csv`` is answered from it
(`cosim.tune.evaluations`), so the resumed tuning ends where an uninterrupted one would.
"""
from __future__ import annotations

import hashlib
import inspect
import json
import os
import shlex
import sys
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SetupError
from ..safeio import lock_output, write_atomic
from ..plan.prepare import Prepared, load_scenario, prepare_scenario
from ..record.metadata import signal_info
from ..run.simulation import run
from ..sweep.dispatch import Executor
from ..sweep.values import _seed_parameters, identity_of
from .engines import engine
from .evaluations import Evaluation, Evaluator, Objective, make_task, read_known, schema_of
from .measures import CallableTerm, Constraint, Measurement, MetricTerm, parse_constraint, parse_term, \
    resolve_setpoints, shippable
from .optimizers import METHODS, DifferentialEvolution, NelderMead
from .space import Parameter, SearchSpace, as_parameter, parse_parameter

__all__ = ["CallableTerm", "Constraint", "DifferentialEvolution", "MetricTerm", "NelderMead", "Parameter",
           "TuneResult", "read_evaluations", "tune"]

#: evaluations when none is given
DEFAULT_EVALUATIONS = 300


@dataclass
class TuneResult:
    """Every evaluation in order, the best, and the files written."""
    evaluations: list[Evaluation]
    best: Evaluation | None
    message: str
    seconds: float
    output: Path
    table: Path
    ssv: Path | None = None
    result: Path | None = None
    report: Path | None = None
    convergence: Path | None = None
    command: str = ""
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, float | int]:
        """The best point's values (empty when no evaluation completed)."""
        return dict(self.best.values) if self.best is not None else {}

    @property
    def ran(self) -> int:
        """Evaluations run now (not answered from an earlier tuning's table)."""
        return sum(not ev.replayed for ev in self.evaluations)

    @property
    def failed(self) -> list[Evaluation]:
        return [ev for ev in self.evaluations if ev.status != "completed"]


ObjectiveSpec = str | MetricTerm | CallableTerm | Callable[[np.ndarray], float]


def _objective_terms(objective: ObjectiveSpec | Sequence[ObjectiveSpec]) -> list[tuple[float, Any]]:
    items = [objective] if isinstance(objective, (str, MetricTerm, CallableTerm)) or callable(objective) \
        else list(objective)
    if not items:
        raise SetupError("no objective: give --objective METRIC:SIGNAL (e.g. ITAE:plant.y).", element="--objective")
    terms = []
    for item in items:
        if isinstance(item, str):
            terms.append(parse_term(item))
        elif isinstance(item, tuple) and len(item) == 2:      # (weight, term)
            weight, term = item
            terms.append((float(weight), _objective_terms(term)[0][1]))
        elif isinstance(item, (MetricTerm, CallableTerm)):
            terms.append((1.0, item))
        elif callable(item):
            terms.append((1.0, CallableTerm(item)))
        else:
            raise SetupError(f"an objective is a text METRIC:SIGNAL, a callable on the result or (weight, "
                             f"either), not {item!r}.", element="objective")
    return terms


def _constraints(constraints: Sequence[str | Constraint]) -> list[Constraint]:
    return [c if isinstance(c, Constraint) else parse_constraint(c) for c in constraints]


def _describe_term(term: Any) -> Any:
    """What identifies a term in the settings: a metric term's fields, a callable's name and source."""
    if isinstance(term, MetricTerm):
        return [term.metric, term.signal, term.setpoint, term.events]
    try:
        source = inspect.getsource(term.function)
    except (OSError, TypeError):
        source = getattr(term.function, "__qualname__", repr(term.function))
    return [term.name, hashlib.sha256(source.encode()).hexdigest()[:16]]


def loops_of(prepared: Prepared) -> tuple[list[list[str]], list[str], list[str]]:
    """The control loops (set-point, measured) and disturbances a report of this scenario shows
    (`cosim.present.report`), and the recorded signals."""
    from ..present.plots import default_panels, disturbances, setpoints

    outputs, inputs = prepared.plan.recorded()
    names = outputs + inputs
    metadata = signal_info(prepared.plan)
    loops = [p for p in default_panels(metadata, names) if len(p) == 2 and p[0] in setpoints(metadata, names)]
    return loops, disturbances(metadata, names), names


def check_tune_folder(path: Path) -> Path:
    """``path`` if the tuning can write there: a folder, or none yet under a writable folder."""
    if path.exists() and not path.is_dir():
        raise SetupError(f"{path} is a file; a tuning's output is a folder (for tune.csv, best.ssv, tune.html).",
                         element="--output")
    existing = next(p for p in (path.resolve(), *path.resolve().parents) if p.exists())
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise SetupError(f"{path}: {existing} is not a writable folder.", element="--output")
    return path


def tune(scenario: str | Path, parameters: Mapping[str, Any] | Sequence[str | Parameter], *,
         objective: ObjectiveSpec | Sequence[ObjectiveSpec], constraints: Sequence[str | Constraint] = (),
         method: str | DifferentialEvolution | NelderMead = "differential-evolution",
         max_evaluations: int = DEFAULT_EVALUATIONS, seed: int = 0, seeds: Sequence[int] = (),
         seed_parameters: Sequence[str] = (), disturbances: Sequence[str] | None = None, band: float = 0.02,
         parameter_sets: Sequence[str | Path] = (), start_values: Sequence[str] = (),
         input_file: str | Path | None = None, fmu_dirs: Sequence[str | Path] = (),
         start_time: float | None = None, stop_time: float | None = None, step_size: float | None = None,
         algorithm: str | None = None, output: str | Path | None = None, executor: Executor = "process",
         workers: int | None = None, reuse: bool = True, force: bool = False, progress: bool = False,
         report: bool = True) -> TuneResult:
    """Tune ``parameters`` of ``scenario`` (see the module docstring).

    ``parameters``: ``{"controller.Kc": (0.1, 10, "log"), "controller.Ti": (1, 100)}``, or the
    texts ``"controller.Kc=0.1:10:log"``, or `Parameter` s.  ``objective``: a term text
    (``"ITAE:plant.y"``, ``"0.5*overshoot:plant.y"``), a callable on the result (a NumPy
    structured array) returning a number, or a list of them, summed; ``constraints``: texts
    (``"overshoot:plant.y<=10%"``) or `Constraint` s.  ``method``: "differential-evolution"
    (`DifferentialEvolution`, its settings as an instance), "nelder-mead" (`NelderMead`).
    ``max_evaluations``: the most points evaluated; ``seed``: the optimiser's random seed (the
    same seed, settings and scenario give the same tuning); ``seeds``: noise seeds, each point
    run once per seed on every component's ``seed`` parameter (or ``seed_parameters``) and
    averaged.  ``disturbances``: the signals whose steps are events of their own (default: those
    the report finds, the signals driving a plant input ``d``).  The rest as `cosim.sweep.sweep`.

    Raises `SetupError` before any run for a bad name, bound, term or option.
    """
    began = time.perf_counter()
    scenario_text, scenario = scenario, Path(scenario).resolve()
    optimizer = METHODS[method]() if isinstance(method, str) and method in METHODS else method
    if not isinstance(optimizer, (DifferentialEvolution, NelderMead)):
        raise SetupError(f"unknown method {method!r}; give one of {', '.join(METHODS)}.", element="--method")
    if max_evaluations < 1:
        raise SetupError(f"--max-evaluations {max_evaluations}: give at least 1.", element="--max-evaluations")
    wanted = [parse_parameter(p) if isinstance(p, str) else p for p in parameters] if not isinstance(parameters, Mapping) \
        else [as_parameter(name, spec) for name, spec in parameters.items()]
    weighted = _objective_terms(objective)
    limits = _constraints(constraints)
    started = {text.partition("=")[0].strip() for text in start_values}
    clash = sorted(started & {p.name for p in wanted})
    if clash:
        raise SetupError(f"{', '.join(clash)} is both tuned and given a start value.", element="--start-value")
    parameter_sets = [Path(p).resolve() for p in parameter_sets]
    inputs = None if input_file is None else Path(input_file).resolve()
    fmu_dirs = [Path(d).resolve() for d in fmu_dirs]
    output = check_tune_folder(Path(output) if output is not None else Path("results") / f"{scenario.stem}_tune")

    loaded = load_scenario(scenario, parameter_sets=parameter_sets, fmu_dirs=fmu_dirs, input_file=inputs)
    with ExitStack() as stack:
        stack.enter_context(loaded)
        prepared = prepare_scenario(loaded, start_time=start_time, stop_time=stop_time, step_size=step_size,
                                    algorithm=algorithm, start_values=start_values)
        space = SearchSpace.of(prepared, wanted)
        loops, found_disturbances, recorded = loops_of(prepared)
        resolved = resolve_setpoints([t for _, t in weighted], loops, recorded, "--objective")
        weighted = [(w, t) for (w, _), t in zip(weighted, resolved)]
        limits = [Constraint(t, c.upper, c.lower) for c, t in
                  zip(limits, resolve_setpoints([c.term for c in limits], loops, recorded, "--constraint"))]
        loads = tuple(found_disturbances if disturbances is None else disturbances)
        for name in loads:
            if name not in recorded:
                from ..errors import did_you_mean
                raise SetupError(f"no recorded signal '{name}'.", element="--disturbance", variable=name,
                                 hint=did_you_mean(name, recorded))
        names = [t.name for _, t in weighted]
        if len(set(names)) != len(names):
            raise SetupError(f"an objective term is given twice ({', '.join(sorted({n for n in names if names.count(n) > 1}))}).",
                             element="--objective")
        goal = Objective(tuple((t.name, w) for w, t in weighted), tuple(limits))
        seed_names = _seed_parameters(prepared, seed_parameters) if seeds else []
        measurement = Measurement(tuple([t for _, t in weighted] + [c.term for c in limits]), loads, band,
                                  prepared.grid.stop)
        if executor != "serial":
            measurement = shippable(measurement)
        identity = identity_of(prepared, parameter_sets, start_values, inputs)
        context = {"scenario": identity, "parameters": [[p.name, p.type] for p in space.parameters],
                   "objective": [[w, _describe_term(t)] for w, t in weighted],
                   "constraints": [[_describe_term(c.term), c.lower, c.upper] for c in limits],
                   "disturbances": list(loads), "band": band, "seeds": list(seeds), "seed_parameters": seed_names}
        digest = hashlib.sha256(json.dumps(context, sort_keys=True).encode()).hexdigest()
        settings = {"scenario": str(scenario), "parameters": space.describe(), "objective": goal.describe(),
                    "constraints": [c.text() for c in limits], "disturbances": list(loads), "method": optimizer.name,
                    "optimizer": {k: v for k, v in vars(optimizer).items()}, "max_evaluations": max_evaluations,
                    "seed": seed, "seeds": list(seeds), "seed_parameters": seed_names,
                    "parameter_sets": [str(p) for p in parameter_sets], "start_values": list(start_values),
                    "grid": [prepared.grid.start, prepared.grid.stop, prepared.grid.step], "context": digest,
                    "columns": [list(c) for c in schema_of(space, goal).columns]}

        csv, parquet, meta = output / "tune.csv", output / "tune.parquet", output / "tune.json"
        for table in (csv, parquet):
            stack.enter_context(lock_output(table))
        known = {} if force else _earlier(meta, csv, digest, space, goal)
        if force:
            for old in (csv, parquet):
                old.unlink(missing_ok=True)
        write_atomic(meta, json.dumps({"settings": settings}, indent=1))
        bar = None
        if progress:
            from tqdm import tqdm
            bar = stack.enter_context(tqdm(total=max_evaluations, unit="eval", desc=f"tune {scenario.name}",
                                           file=sys.stderr))
        sweep_key = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()
        task = make_task(prepared, scenario, parameter_sets, fmu_dirs, start_values, inputs, sweep_key,
                         measurement, reuse)
        with engine(executor, workers, prepared) as runs:
            evaluator = Evaluator(engine=runs, space=space, objective=goal, measurement=measurement, task=task,
                                  context=context, seeds=seeds, seed_parameters=seed_names, table=(csv, parquet),
                                  known=known, progress=bar)
            finished = False
            try:
                message = optimizer.run(evaluator, max_evaluations, seed)
                finished = True
            finally:
                evaluator.close(finished)
        evaluations, best = evaluator.evaluations, evaluator.best
        result = TuneResult(evaluations, best, message, time.perf_counter() - began, output, csv, settings=settings)
        if best is not None:
            fixed = [*start_values, *([f"{n}={seeds[0]}" for n in seed_names] if seeds else [])]
            given = [("--fmu-dir", d) for d in fmu_dirs] + [("--param-set", p) for p in parameter_sets] + \
                [("--param-set", output / "best.ssv")] + [("--start-value", v) for v in fixed] + \
                [(o, v) for o, v in (("--input-file", input_file), ("--start", start_time), ("--stop", stop_time),
                                     ("--step", step_size), ("--algorithm", algorithm)) if v is not None]
            result.command = shlex.join(["cosim", "run", str(scenario_text), *[str(x) for o, v in given for x in (o, v)]])
            result.ssv = _write_outputs(result, prepared, loaded, space, goal, fixed, seeds, optimizer.name, report)
        result.seconds = time.perf_counter() - began
        write_atomic(meta, json.dumps({"settings": settings, "result": _summary(result)}, indent=1))
        return result


def read_evaluations(folder: str | Path) -> list[dict[str, Any]]:
    """The rows of a tuning's ``tune.csv`` in ``folder``, each column typed as its ``tune.json`` says."""
    from ..sweep.table import Schema, read_table

    folder = Path(folder)
    try:
        columns = json.loads((folder / "tune.json").read_text())["settings"]["columns"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SetupError(f"not a tuning's folder: no readable tune.json ({e}).", file=str(folder)) from None
    return read_table(folder / "tune.csv", Schema(tuple(tuple(c) for c in columns)))


def _earlier(meta: Path, csv: Path, digest: str, space: SearchSpace, goal: Objective) -> dict[str, Evaluation]:
    """An earlier tuning's evaluations in the folder, when its settings decide rows the same way."""
    if not meta.is_file():
        if csv.is_file():
            raise SetupError(f"{csv} is there without its tune.json; give --force to start again or another --output.",
                             file=str(csv))
        return {}
    try:
        earlier = json.loads(meta.read_text())["settings"]["context"]
    except (ValueError, KeyError, TypeError):
        raise SetupError("not a tuning's settings (tune.json); give --force to start again.", file=str(meta)) from None
    if earlier != digest:
        raise SetupError("the folder holds a tuning whose scenario, parameters, objective, constraints or seeds differ "
                         "from these, so its evaluations cannot be reused; give --force to start again or another "
                         "--output.", file=str(meta))
    try:
        return read_known(csv, space, goal)
    except (ValueError, KeyError, UnicodeDecodeError) as e:
        raise SetupError(f"cannot read the earlier tuning's table ({e}); give --force to start again.",
                         file=str(csv)) from None


def _write_outputs(result: TuneResult, prepared: Prepared, loaded, space: SearchSpace, goal: Objective,
                   fixed: Sequence[str], seeds: Sequence[int], method: str, report: bool) -> Path:
    """best.ssv, and with ``report`` the best run (best.csv, best.json; ``fixed``: its start values, the
    first noise seed's among them), convergence.png and tune.html."""
    from ..present.report import write_report
    from .output import summary, write_best, write_convergence

    output, best, settings = result.output, result.best, result.settings
    ssv = write_best(output / "best.ssv", space, best, name=f"best of cosim tune (evaluation {best.index})")
    if not report:
        return ssv
    grid = prepared.grid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)    # the tuning's plan has warned already
        again = prepare_scenario(loaded, parameter_sets=[ssv], start_values=fixed, start_time=grid.start,
                                 stop_time=grid.stop, step_size=grid.step, algorithm=prepared.algorithm)
    result.result = output / "best.csv"
    run(again, output=result.result)
    title = f"{Path(settings['scenario']).name}: {method}, {len(result.evaluations)} evaluations"
    result.convergence, png = write_convergence(output / "convergence.png", result.evaluations, space, goal, title)
    section = summary(scenario=Path(settings["scenario"]).name, method=method, message=result.message, space=space,
                      objective=goal, evaluations=result.evaluations, best=best, seeds=seeds, png=png,
                      command=result.command, seconds=result.seconds)
    result.report = write_report(result.result, output / "tune.html", before=section)
    return ssv


def _summary(result: TuneResult) -> dict[str, Any]:
    best = result.best
    return {"message": result.message, "evaluations": len(result.evaluations), "ran": result.ran,
            "failed": len(result.failed), "seconds": result.seconds,
            "best": None if best is None else {"evaluation": best.index, "parameters": best.values,
                                               "objective": best.objective, "feasible": best.feasible,
                                               "terms": best.terms, "constraints": best.constraints},
            "files": {k: None if v is None else str(v) for k, v in
                      (("table", result.table), ("ssv", result.ssv), ("result", result.result),
                       ("report", result.report), ("convergence", result.convergence))}}
