"""What a sweep runs: the swept values typed by their FMU variables, the run ids, the metrics
asked for, and each run's parameter set as an SSP 1.0 ``.ssv`` file."""
from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import product
from pathlib import Path

from ..model.fmu import exchange_type
from ..errors import SetupError, did_you_mean
from ..present.metrics import METRICS
from ..plan.parameters import check_values, split_system_name
from ..plan.values import MAX_RUNS, Value, typed_values
from ..safeio import write_atomic
from ..plan.prepare import Prepared
from ..read.ssp import NS
from ..model.structure import ParameterValue

SOURCE = "cosim sweep --set"


@dataclass(frozen=True)
class Metric:
    """Step metrics of ``signal`` following ``setpoint`` (see `cosim.present.metrics.step_metrics`)."""
    signal: str
    setpoint: str

    def columns(self) -> list[str]:
        return [f"{self.signal}:{m}" for m in METRICS]

    def reason_column(self) -> str:
        """The column saying why a metric of this signal is undefined (`cosim.present.metrics.Response.reasons`)."""
        return f"undefined({self.signal})"


def parse_set(text: str) -> tuple[str, list[str]]:
    """``comp.var=v1,v2,...`` (each item may be a range ``start:stop:count``) -> name, items."""
    name, sep, values = text.partition("=")
    if not sep or not name.strip() or not values.strip():
        raise SetupError(f"'{text}' is not NAME=VALUE[,VALUE...] (e.g. controller.Kc=2,4,8 or "
                         "controller.Kc=2:8:4 for 4 values from 2 to 8).", element="--set")
    return name.strip(), [v.strip() for v in values.split(",")]


def parse_seeds(text: str) -> Sequence[int]:
    """``1..20`` (inclusive; a lazy range, so a huge one costs nothing before `plan_runs` refuses
    it) or ``1,5,9`` -> the seeds."""
    try:
        if ".." in text:
            first, last = (int(x) for x in text.split(".."))
            if last < first:
                raise ValueError
            return range(first, last + 1)
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


def _check_size(typed: Mapping[str, Sequence[Value]], seeds: Sequence[int]) -> None:
    """Refuse a sweep of more than MAX_RUNS runs, naming its size, before anything is allocated."""
    counts = [len(v) for v in typed.values()] + ([len(seeds)] if seeds else [])
    if math.prod(counts) > MAX_RUNS:
        factors = [f"{n} values of {name}" for name, n in zip(typed, counts)] + \
                  ([f"{len(seeds)} seeds"] if seeds else [])
        raise SetupError(f"the sweep has {math.prod(counts):,} runs ({' x '.join(factors)}); one sweep may "
                         f"have at most {MAX_RUNS:,}.", element="--set" if typed else "--seeds",
                         hint="Split it into several sweeps into the same --output folder.")


# --------------------------------------------------------------------------- planning

@dataclass
class Run:
    index: int
    run_id: str
    values: dict[str, Value]
    seed: int | None
    parameters: list[ParameterValue]


def _variable(prepared: Prepared, name: str):
    """The FMU variable behind ``comp.var``, or the master's own message for an unknown name."""
    p = ParameterValue(name, "Real", 0.0, SOURCE, 0)
    try:
        comp, var = split_system_name(prepared.plan.components, p)
        return prepared.plan.fmus[comp].variable(var, "", "")
    except SetupError as e:  # said once, as the option: not "cosim sweep --set, --set NAME"
        raise SetupError(e.detail, element=f"--set {name}", hint=e.hint) from None


def _seed_parameters(prepared: Prepared, named: Sequence[str]) -> list[str]:
    if named:
        return list(named)
    found = [f"{comp}.seed" for comp, desc in prepared.plan.fmus.items()
             if "seed" in desc.variables and desc.variables["seed"].causality == "parameter"]
    if not found:
        raise SetupError("--seeds given, but no component of the scenario has a parameter named 'seed'; "
                         "name the parameter to set with --seed-parameter COMPONENT.VARIABLE.",
                         file=prepared.plan.files.display, element="--seeds")
    return found


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def identity_of(prepared: Prepared, parameter_sets: Sequence[Path], start_values: Sequence[str],
                input_file: Path | None) -> dict:
    """Everything outside the swept values that decides a run's result (with the --start-value
    texts and the input table's contents)."""
    scenario = prepared.plan.files
    if scenario.archive is not None:
        files = {scenario.archive.name: _digest(scenario.archive)}
    else:
        files = {p.name: _digest(p) for p in sorted(scenario.base_dir.iterdir())
                 if p.suffix.lower() in (".ssd", ".ssv") and p.is_file()}
    grid = prepared.grid
    return {"scenario": files,
            "fmus": {name: [d.guid, _digest(d.path)] for name, d in prepared.plan.fmus.items()},
            "parameter_sets": [_digest(Path(p)) for p in parameter_sets],
            "grid": [grid.start, grid.stop, grid.step], "algorithm": prepared.algorithm,
            **({"start_values": list(start_values)} if start_values else {}),
            **({"input_file": _digest(input_file)} if input_file is not None else {})}


def _run_id(identity: dict, parameters: list[ParameterValue]) -> str:
    key = json.dumps({**identity, "parameters": [[p.name, p.type, p.value] for p in parameters]},
                     sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def plan_runs(prepared: Prepared, sets: Mapping[str, Sequence[Value]], seeds: Sequence[int],
               seed_parameters: Sequence[str], identity: dict) -> tuple[list[Run], dict[str, str]]:
    """Type every value, check every name and value with the master's validation, and list the runs."""
    types: dict[str, str] = {}
    typed: dict[str, list[Value]] = {}
    for name, raw_values in sets.items():
        if not raw_values:
            raise SetupError("no values given.", element="--set", variable=name)
        types[name] = exchange_type(_variable(prepared, name))
        typed[name] = list(dict.fromkeys(v for raw in raw_values for v in typed_values(raw, types[name], name)))
    _check_size(typed, seeds)
    seed_names = _seed_parameters(prepared, seed_parameters) if seeds else []
    for name in seed_names:
        types[name] = exchange_type(_variable(prepared, name))
    overlap = set(seed_names) & set(sets)
    if overlap:
        raise SetupError(f"{', '.join(sorted(overlap))} is both swept with --set and set by --seeds.",
                         element="--set")
    every = [ParameterValue(name, types[name], v, SOURCE, 0) for name, vs in typed.items() for v in vs]
    every += [ParameterValue(name, types[name], typed_values(s, types[name], name, "--seeds")[0],
                             "cosim sweep --seeds", 0) for name in seed_names for s in seeds]
    check_values(prepared.plan, every)      # the master's messages for names, types, ranges
    runs = []
    for index, combo in enumerate(product(*typed.values(), *([seeds] if seeds else []))):
        values = dict(zip(typed, combo))
        seed = combo[-1] if seeds else None
        parameters = [ParameterValue(n, types[n], v, SOURCE, 0) for n, v in values.items()]
        parameters += [ParameterValue(n, types[n], typed_values(seed, types[n], n)[0], SOURCE, 0) for n in seed_names]
        runs.append(Run(index, _run_id(identity, parameters), values, seed, parameters))
    return runs, types


def check_metrics(prepared: Prepared, metrics: Sequence[Metric]) -> None:
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
    write_atomic(path, etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))
