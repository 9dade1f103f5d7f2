"""Evaluating points of a tuning: each point a co-simulation per noise seed on the engine
(`cosim.tune.engines`), measured in the worker (`cosim.tune.measures.Measurement`), the
objective the weighted sum of the terms' means over the seeds and each constraint its worst
seed; one row per evaluation in ``tune.csv`` (and ``tune.parquet`` with pyarrow), written as
evaluations finish (`cosim.sweep.batch.BatchedTable`), so an interrupted tuning keeps them.

An evaluation's key is a hash of what decides its row: the scenario and its FMUs, parameter
sets, start values, input table and grid (`cosim.sweep.values.identity_of`), the terms and
constraints measured, the seeds, and the point's values.  The rows of an earlier tuning with
the same settings are read back as answers (`Evaluator.known`): a tuning run again replays
its optimiser from the start (the same seed proposes the same points, since every answer is
the same), asks no run of a point already in the table, and goes on from where it stopped.
"""
from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..safeio import max_unpacked_bytes
from ..plan.prepare import Prepared
from ..sweep.batch import BatchedTable
from ..sweep.dispatch import Task
from ..sweep.table import Schema, read_table, write_table
from .engines import Engine
from .measures import ERROR_COLUMN, Constraint, Measurement
from .space import SearchSpace

@dataclass(frozen=True)
class Objective:
    """The weighted sum of terms (their names, as `Measurement` columns) and the constraints."""
    weights: tuple[tuple[str, float], ...]
    constraints: tuple[Constraint, ...] = ()

    def value(self, terms: Mapping[str, float | None]) -> float | None:
        if any(terms.get(name) is None for name, _ in self.weights):
            return None
        return float(sum(w * terms[name] for name, w in self.weights))

    def describe(self) -> str:
        return " + ".join(name if w == 1 else f"{w:g}*{name}" for name, w in self.weights)


@dataclass
class Evaluation:
    """One point: its values, what its runs gave and what the optimiser sees (`value`).  ``status``:
    "completed" (every run completed, every term measured), "failed" (a run failed: its error
    code and message) or "unmeasured" (a term undefined: why)."""
    index: int
    batch: int
    key: str
    values: dict[str, float | int]
    status: str
    message: str | None = None
    error: str | None = None
    objective: float | None = None
    #: each objective term's mean over the seeds
    terms: dict[str, float | None] = field(default_factory=dict)
    #: each constraint's worst value over the seeds, by its text
    constraints: dict[str, float | None] = field(default_factory=dict)
    violation: float = 0.0
    run_seconds: float = 0.0
    #: answered from an earlier tuning's table, not run now
    replayed: bool = False

    @property
    def feasible(self) -> bool:
        return self.status == "completed" and self.violation == 0

    @property
    def value(self) -> float:
        """The objective for the optimiser: +inf where there is none (a failed run, an undefined metric)."""
        return math.inf if self.objective is None else self.objective


def schema_of(space: SearchSpace, objective: Objective) -> Schema:
    columns = [("evaluation", "int64"), ("batch", "int64"), ("key", "string")]
    columns += [(p.name, "int64" if p.type == "Integer" else "float64") for p in space.parameters]
    columns += [("status", "string"), ("error", "string"), ("message", "string"), ("objective", "float64")]
    columns += [(name, "float64") for name, _ in objective.weights]
    columns += [(c.text(), "float64") for c in objective.constraints]
    columns += [("violation", "float64"), ("feasible", "bool"), ("best", "float64"), ("run_seconds", "float64")]
    return Schema(tuple(dict.fromkeys(columns)))


def row_of(ev: Evaluation, best: float | None) -> dict[str, Any]:
    return {"evaluation": ev.index, "batch": ev.batch, "key": ev.key, **ev.values, "status": ev.status,
            "error": ev.error, "message": ev.message, "objective": ev.objective, **ev.terms, **ev.constraints,
            "violation": ev.violation, "feasible": ev.feasible, "best": best, "run_seconds": ev.run_seconds}


def evaluation_of(row: Mapping[str, Any], space: SearchSpace, objective: Objective) -> Evaluation:
    """An evaluation read back from its table row."""
    return Evaluation(row["evaluation"], row["batch"], row["key"], {n: row[n] for n in space.names}, row["status"],
                      row.get("message"), row.get("error"), row.get("objective"),
                      {name: row.get(name) for name, _ in objective.weights},
                      {c.text(): row.get(c.text()) for c in objective.constraints}, row["violation"],
                      row.get("run_seconds") or 0.0, replayed=True)


def better(a: Evaluation | None, b: Evaluation) -> bool:
    """Whether ``b`` beats ``a``: feasible beats infeasible, then the lower objective; among
    infeasible ones the smaller violation (a failed or unmeasured one last)."""
    if a is None:
        return True
    if a.feasible != b.feasible:
        return b.feasible
    if b.feasible:
        return b.value < a.value
    return (b.violation, b.value) < (a.violation, a.value)


class Evaluator:
    """Runs points on an engine, keeps every evaluation in order and the table up to date."""

    def __init__(self, *, engine: Engine, space: SearchSpace, objective: Objective, measurement: Measurement,
                 task: Callable[[str, list[str]], Task], context: Mapping[str, Any], seeds: Sequence[int],
                 seed_parameters: Sequence[str], table: tuple[Path, Path], known: Mapping[str, Evaluation],
                 progress: Any = None):
        self.engine, self.space, self.objective, self.measurement = engine, space, objective, measurement
        self._task = task
        self._context = hashlib.sha256(json.dumps(context, sort_keys=True).encode()).hexdigest()
        self.seeds, self.seed_parameters = list(seeds), list(seed_parameters)
        self.known = dict(known)
        self.evaluations: list[Evaluation] = []
        self._by_key: dict[str, Evaluation] = {}
        self.batches = 0
        self.best: Evaluation | None = None
        self.progress = progress
        self.schema = schema_of(space, objective)
        csv, parquet = table
        self._write = lambda rows: write_table(self._with_best(rows), self.schema, csv, parquet)
        # the earlier rows stay in the table until this tuning's evaluations replace them
        self._rows = {ev.index: row_of(ev, None) for ev in self.known.values()}
        # rewritten at most about every 20 rewrite durations, a row in within 2 s (a rewrite of 240 rows
        # with Parquet takes ~40 ms, in the process that hands the runs out: ~2 % of its time)
        self.table = BatchedTable(self._rows, self._write, spacing=20.0, delay=2.0)

    def key(self, values: Mapping[str, float | int]) -> str:
        text = json.dumps([self._context, [[n, values[n]] for n in self.space.names]])
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def __call__(self, points: Sequence[Sequence[float]]) -> list[Evaluation]:
        """Evaluate ``points`` (the optimiser's coordinates) as one batch, in parallel."""
        batch, self.batches = self.batches, self.batches + 1
        out: list[Evaluation | None] = [None] * len(points)
        waiting: dict[str, tuple[Evaluation, list[int], list[dict[str, Any]]]] = {}
        tasks: list[Task] = []
        by_run: dict[str, str] = {}          # run id -> the key of its point
        for pos, x in enumerate(points):
            values = self.space.values(x)
            key = self.key(values)
            if key in self._by_key:          # a point asked for again: its first answer
                out[pos] = self._by_key[key]
                continue
            if key in waiting:
                waiting[key][1].append(pos)
                continue
            ev = Evaluation(len(self.evaluations), batch, key, values, "completed")
            self.evaluations.append(ev)
            self._by_key[key] = ev
            if key in self.known:
                old = self.known[key]
                ev = self._replace(ev, Evaluation(ev.index, batch, key, values, old.status, old.message, old.error,
                                                  old.objective, old.terms, old.constraints, old.violation,
                                                  old.run_seconds, replayed=True))
                out[pos] = ev
                self._finished(ev)
                continue
            waiting[key] = (ev, [pos], [])
            for seed in self.seeds or [None]:
                texts = [f"{n}={v!r}" for n, v in values.items()]
                texts += [f"{n}={seed}" for n in self.seed_parameters] if seed is not None else []
                tasks.append(self._task(self._run_id(key, seed), texts))
                by_run[tasks[-1].run_id] = key

        def done(task: Task, row: dict[str, Any]) -> None:
            key = by_run[task.run_id]
            ev, positions, rows = waiting[key]
            rows.append(row)
            if len(rows) == len(self.seeds or [None]):
                ev = self._replace(ev, self._measured(ev, rows))
                for p in positions:
                    out[p] = ev
                self._finished(ev)

        self.engine.run(tasks, done)
        return out

    def _replace(self, old: Evaluation, new: Evaluation) -> Evaluation:
        self.evaluations[old.index] = new
        self._by_key[new.key] = new
        return new

    def _run_id(self, key: str, seed: int | None) -> str:
        return key if seed is None else hashlib.sha256(f"{key}/{seed}".encode()).hexdigest()[:16]

    def _measured(self, ev: Evaluation, rows: list[dict[str, Any]]) -> Evaluation:
        """The evaluation of a point from its runs' rows (one per seed)."""
        seconds = float(sum(r.get("wall_time") or 0.0 for r in rows))
        failed = [r for r in rows if r.get("status") != "completed"]
        names = self.measurement.names
        if failed:
            first = failed[0]
            where = f" (seed {self.seeds[rows.index(first)]})" if self.seeds else ""
            return Evaluation(ev.index, ev.batch, ev.key, ev.values, "failed", f"{first.get('message')}{where}",
                              first.get("error") or "unexpected", None, dict.fromkeys(n for n, _ in self.objective.weights),
                              {c.text(): None for c in self.objective.constraints}, math.inf, seconds)
        means = {n: None if any(r.get(n) is None for r in rows) else float(np.mean([r[n] for r in rows]))
                 for n in names}
        constraints = {}
        for c in self.objective.constraints:
            values = [r.get(c.name) for r in rows]
            constraints[c.text()] = None if any(v is None for v in values) else \
                float(max(values) if c.upper < math.inf else min(values))
        why = "; ".join(dict.fromkeys(r[ERROR_COLUMN] for r in rows if r.get(ERROR_COLUMN)))
        terms = {n: means[n] for n, _ in self.objective.weights}
        objective = self.objective.value(terms)
        violation = float(sum(c.violation(math.nan if constraints[c.text()] is None else constraints[c.text()])
                              for c in self.objective.constraints))
        status = "completed" if objective is not None and all(v is not None for v in constraints.values()) \
            else "unmeasured"
        return Evaluation(ev.index, ev.batch, ev.key, ev.values, status, why or None, None, objective, terms,
                          constraints, violation if status == "completed" else math.inf, seconds)

    def _finished(self, ev: Evaluation) -> None:
        if better(self.best, ev) and (ev.status == "completed"):
            self.best = ev
        self.table.add(ev.index, row_of(ev, None))
        if self.progress is not None:
            best = self.best
            self.progress.set_postfix_str("best " + ("-" if best is None else
                                                     f"{best.value:.6g}{'' if best.feasible else ' (infeasible)'} "
                                                     f"at #{best.index}"), refresh=False)
            self.progress.update()

    def _with_best(self, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """The rows (in evaluation order) with ``best``: the lowest feasible objective up to each."""
        best, out = None, []
        for row in rows:
            if row.get("feasible") and row.get("objective") is not None:
                best = row["objective"] if best is None else min(best, row["objective"])
            out.append({**row, "best": best})
        return out

    def close(self, finished: bool) -> None:
        """Write the table; ``finished`` (the optimiser ended): without the earlier tuning's rows
        this one did not reach."""
        self.table.close()
        stale = [i for i in self._rows if i >= len(self.evaluations)] if finished else []
        if stale:
            for index in stale:
                del self._rows[index]
            self._write([self._rows[i] for i in sorted(self._rows)])


def read_known(csv: Path, space: SearchSpace, objective: Objective) -> dict[str, Evaluation]:
    """The evaluations of an earlier tuning's table, by key."""
    if not csv.is_file():
        return {}
    rows = read_table(csv, schema_of(space, objective))
    return {row["key"]: evaluation_of(row, space, objective) for row in rows if row.get("key")}


def make_task(prepared: Prepared, scenario: Path, parameter_sets: Sequence[Path], fmu_dirs: Sequence[Path],
              start_values: Sequence[str], input_file: Path | None, sweep_key: str, measurement: Measurement,
              reuse: bool) -> Callable[[str, list[str]], Task]:
    """A function making the `Task` of one run: the tuning's fixed inputs, the run's values as
    start values (applied last, as a parameter set given last would be)."""
    grid = prepared.grid

    def task(run_id: str, values: list[str]) -> Task:
        return Task(run_id, str(scenario), tuple(str(p) for p in parameter_sets), tuple(str(d) for d in fmu_dirs),
                    grid.start, grid.stop, grid.step, prepared.algorithm, f"{run_id}.csv",   # no file: run_files=False
                    (), max_unpacked_bytes()[0], (*start_values, *values),
                    None if input_file is None else str(input_file), shared_sets=len(parameter_sets),
                    sweep_key=sweep_key, reuse=reuse, run_files=False, measure=measurement)
    return task

