"""What one communication step of an FMU of ours costs where users run it, against pythonfmu's floor
and the FMU's own law (issue 42).

    python benchmarks/bench_slave_step.py [--fmus PID FOPDT GrayPredictivePI PID3] [--baseline DIR]
                                          [--hosts c cosim fmpy] [--steps 1000] [--rounds 31] [--json F]
    python benchmarks/bench_slave_step.py --decompose [--tree DIR] [--fmus PID ...]
    python benchmarks/bench_slave_step.py --system ssp/pid_fopdt [--baseline DIR]

A step is what a master does per FMU: set its Real inputs (one batched call), doStep over the
FMU's default step, get its Real outputs (one batched call).  Per model, these FMUs run in one
process, interleaved round by round, and each figure is the best round's CPU time per step (the
machine is shared):

- ``floor``: pythonfmu's floor, a plain pythonfmu (pythonfmu3 for an FMI 3.0 model) FMU
  ``<Model>Floor`` with the model's variables (names, types, causalities, variabilities, start
  values) whose ``do_step`` does nothing, with pythonfmu's own generic get and set;
- ``law``: the law on that floor, a plain pythonfmu FMU ``<Model>Law`` of our slave class whose
  ``do_step`` only calls ``advance`` and whose get and set are pythonfmu's generic ones on the
  greyfmu objects (nothing of our slave base on the step's path): what the law costs in the host;
- ``ours``: the FMU built from this tree (greyfmu.build, into a temporary folder);
- ``before``: the same model built elsewhere (``--baseline DIR``: a folder of FMUs, e.g. built
  from the commit before a change), in the same process (each FMU's code is private to it,
  greyfmu.privatise).

Hosts: ``c`` (benchmarks/step_host.c, a C program with no Python of its own: our loader starts it;
FMI 2.0 only), ``cosim`` (cosim's compiled loop over the FMU wired to a C peer FMU that feeds its
inputs and reads its outputs, only time kept; the CPU time of `cosim.run.execution.Execution.run`, the peer's share
in every figure), ``fmpy`` (a Python loop over fmpy's ``FMU2Slave``/``FMU3Slave``
``setReal``/``doStep``/``getReal``).  The law alone is ``advance(t, h)`` called in a Python loop
on an instance of the slave class (fmus/, default parameters, the same inputs), in the same rounds.
Printed per model and host: µs per step of each FMU, and what ours and before add to the law on
the floor and to the floor plus the law alone, as multiples of that law; the target (issue 42)
is ours <= floor + law + 1.5 law.

``--decompose`` splits a step of the slave class in Python, with no FMI host (with ``--tree``, the
fmus/ and greyfmu of another tree, e.g. the commit before): the law, the warnings' forwarding per
step (before: ``forward_warnings``, a context entered around every advance; after:
``keep_routing``), the accessors (set_real + get_real, against the floor slave's generic ones),
the rest of ``do_step`` (the input and output checks, the build check), against the floor slave's
set + do_step + get.  The crossing (pythonfmu's C++ wrapper, our loader, the host's calls) is a
host's floor figure less the floor slave's Python calls.

``--system DIR``: cosim's compiled loop over a scenario (its FMUs those of this tree, and of
``--baseline``), interleaved, µs per step.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.append(str(ROOT / "tests"))  # cfmus, ssdgen: after the tree's own folders (tests/cosim would shadow cosim)
HOST_SOURCE = Path(__file__).resolve().parent / "step_host.c"
INPUT_VALUES = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0078125)
"""The inputs' values at every step, in declaration order (as step_host.c sets them)."""


def tree_on_path(tree: Path) -> None:
    """Import greyfmu and the slaves from ``tree`` (before anything of greyfmu is imported)."""
    sys.path[:0] = [str(tree), str(tree / "fmus"), str(tree / "fmus" / "fmi3")]


# ----------------------------------------------------------------------------------------- the floor


FLOOR2 = '''"""pythonfmu's floor for {model} (benchmarks/bench_slave_step.py): its variables, a do_step doing nothing."""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, Real

VARIABLES = {variables!r}


class {model}Floor(Fmi2Slave):
    description = "pythonfmu's floor for {model}"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        kinds = {{"Real": Real, "Integer": Integer, "Boolean": Boolean}}
        for name, kind, causality, variability, start in VARIABLES:
            setattr(self, name, start)
            extra = {{"initial": Fmi2Initial.exact}} if causality == "output" else {{}}
            self.register_variable(kinds[kind](name, causality=Fmi2Causality[causality],
                                               variability=Fmi2Variability[variability], **extra))

    def do_step(self, current_time, step_size):
        return True
'''

FLOOR3 = '''"""pythonfmu3's floor for {model} (benchmarks/bench_slave_step.py): its variables, a do_step doing nothing."""
from pythonfmu3 import Fmi3Causality, Fmi3Slave, Fmi3StepResult, Fmi3Variability, Float64, Int32

VARIABLES = {variables!r}
STEPPED = Fmi3StepResult()


class {model}Floor(Fmi3Slave):

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "pythonfmu3's floor for {model}"
        self.time = 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name, kind, causality, variability, start in VARIABLES:
            setattr(self, name, start)
            self.register_variable({{"Float64": Float64, "Int32": Int32}}[kind](
                name, causality=Fmi3Causality[causality], variability=Fmi3Variability[variability]))

    def do_step(self, current_time, step_size):
        return STEPPED
'''


def floor_variables(fmu: Path) -> tuple[str, list[tuple]]:
    """The FMI version and (name, type, causality, variability, start) of the parameters, inputs and outputs."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu), validate=False)
    kept = []
    for v in md.modelVariables:
        if v.causality not in ("parameter", "input", "output"):
            continue
        kind = {"Enumeration": "Int32" if md.fmiVersion.startswith("3") else "Integer"}.get(v.type, v.type)
        start = 0.0 if v.start is None else v.start
        start = {"Real": float, "Float64": float, "Integer": int, "Int32": int, "Boolean": bool}[kind](
            start if not isinstance(start, str) else (start == "true" if kind == "Boolean" else float(start)))
        kept.append((v.name, kind, v.causality, v.variability, start))
    return md.fmiVersion, kept


def write_floor(fmu: Path, model: str, folder: Path) -> Path:
    """The floor slave's script for the FMU ``fmu`` of ``model`` (see the module docstring)."""
    version, variables = floor_variables(fmu)
    script = folder / f"{model}Floor.py"
    script.write_text((FLOOR3 if version.startswith("3") else FLOOR2).format(model=model, variables=variables))
    return script


def build_floor(fmu: Path, model: str, folder: Path) -> Path:
    """pythonfmu's (pythonfmu3's) floor FMU for ``model``."""
    (folder / "floors").mkdir(parents=True, exist_ok=True)
    script = write_floor(fmu, model, folder / "floors")
    if floor_variables(fmu)[0].startswith("3"):
        from pythonfmu3.builder import FmuBuilder as Fmu3Builder

        return Path(Fmu3Builder.build_FMU(script, dest=folder))
    from pythonfmu.builder import FmuBuilder

    return Path(FmuBuilder.build_FMU(script, dest=folder, needsExecutionTool="false"))


LAW2 = '''"""The law of {model} on pythonfmu's floor (benchmarks/bench_slave_step.py): its slave class with
pythonfmu's generic get and set, its outputs read straight from the greyfmu objects, a do_step that
only advances them."""
from pythonfmu import Fmi2Slave

from {model} import {model}


class {model}Law({model}):
    description = "The law of {model} on pythonfmu's floor"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._ensure_built()  # the outputs' start values are read when the model description is written
        for vr, value in self._outputs.items():
            self.vars[vr].getter = value


def _advance_only(self, current_time, step_size):
    self.advance(current_time, step_size)
    return True


{model}Law.do_step = _advance_only  # set after the class is made, as are the accessors: not wrapped by the base
for _name in ("get_real", "get_integer", "get_boolean", "get_string", "set_real", "set_integer", "set_boolean",
              "set_string"):
    setattr({model}Law, _name, getattr(Fmi2Slave, _name))
'''

LAW3 = '''"""The law of {model} on pythonfmu3's floor (benchmarks/bench_slave_step.py): its slave class with
pythonfmu3's generic get and set, its outputs read straight from the greyfmu objects, a do_step that
only advances them."""
from pythonfmu3 import Fmi3Slave

from _slave3 import STEPPED
from {model} import {model}


class {model}Law({model}, Fmi3Slave):

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "The law of {model} on pythonfmu3's floor"
        self._ensure_built()
        for variable in self.vars.values():
            if variable.name in self._output_values:
                variable.getter = self._output_values[variable.name]


def _advance_only(self, current_time, step_size):
    self.advance(current_time, step_size)
    return STEPPED


{model}Law.do_step = _advance_only  # set after the class is made, as are the accessors: not wrapped by the base
for _name in dir(Fmi3Slave):
    if _name.startswith(("get_", "set_")) and callable(getattr(Fmi3Slave, _name)):
        setattr({model}Law, _name, getattr(Fmi3Slave, _name))
'''


def build_law(model: str, fmi3: bool, folder: Path) -> Path:
    """The law of ``model`` on pythonfmu's (pythonfmu3's) floor as an FMU ``<Model>Law``: what a
    pythonfmu FMU running this law costs with nothing of our slave base on its step's path."""
    from greyfmu import build

    staged = folder / "law-package" / "greyfmu"
    if not staged.is_dir():
        shutil.copytree(build.PACKAGE_DIR, staged, ignore=shutil.ignore_patterns(*build.BUILD_ONLY))
    (folder / "laws").mkdir(parents=True, exist_ok=True)
    script = folder / "laws" / f"{model}Law.py"
    script.write_text((LAW3 if fmi3 else LAW2).format(model=model))
    source = (build.FMI3_SOURCES if fmi3 else build.FMU_SOURCES) / f"{model}.py"
    files = [staged, *(build.SLAVE_FILES3 if fmi3 else build.SLAVE_FILES), source]
    if fmi3:
        from pythonfmu3.builder import FmuBuilder as Fmu3Builder

        built = Path(Fmu3Builder.build_FMU(script, dest=folder, project_files=files))
    else:
        from pythonfmu.builder import FmuBuilder

        built = Path(FmuBuilder.build_FMU(script, dest=folder, project_files=files, needsExecutionTool="false"))
    from testfmus import edited_copy

    # pythonfmu writes the variables' units without their definitions (greyfmu.build adds those):
    # left out, so that the masters accept the model description
    return edited_copy(built, built, lambda text: re.sub(r' unit="[^"]*"', "", text))


# ---------------------------------------------------------------------------------------- the models


def default_step(fmu: Path) -> float:
    from fmpy import read_model_description

    return float(read_model_description(str(fmu), validate=False).defaultExperiment.stepSize)


def ports(fmu: Path) -> tuple[list[tuple[str, int]], list[tuple[str, int]]]:
    """(name, value reference) of the Real inputs and outputs, in declaration order."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu), validate=False)
    real = ("Real", "Float64")
    inputs = [(v.name, v.valueReference) for v in md.modelVariables if v.causality == "input" and v.type in real]
    outputs = [(v.name, v.valueReference) for v in md.modelVariables if v.causality == "output" and v.type in real]
    return inputs, outputs


def slave_class(model: str) -> type:
    """The slave class of ``model`` from fmus/ (or fmus/fmi3/) of the tree on sys.path."""
    import importlib

    return getattr(importlib.import_module(model), model)


def law_timer(model: str, h: float):
    """A function timing ``steps`` advances of a built instance of ``model``'s slave: CPU s per step."""
    cls = slave_class(model)
    slave = cls(instance_name="law", resources=None)
    for name, value in zip(slave._input_names, INPUT_VALUES):
        setattr(slave, name, value)
    slave._ensure_built()
    advance, state = slave.advance, {"t": 0.0}

    def timed(steps: int) -> float:
        t = state["t"]
        began = time.process_time()
        for _ in range(steps):
            advance(t, h)
            t += h
        seconds = time.process_time() - began
        state["t"] = t
        return seconds / steps

    return timed


# -------------------------------------------------------------------------------------------- hosts


def c_host(host: Path, fmus: dict[str, Path], h: float, steps: int, rounds: int,
           folder: Path) -> dict[str, list[float]]:
    """µs per step of every round of each FMU (label -> FMU) in step_host.c; ours before the plain pythonfmu ones."""
    from fmpy import extract, read_model_description

    order = sorted(fmus, key=lambda label: label in ("floor", "law"))  # ours start Python first
    arguments = []
    for label in order:
        md = read_model_description(str(fmus[label]), validate=False)
        unzipped = extract(str(fmus[label]), str(folder / f"c-{label}"))
        inputs, outputs = ports(fmus[label])
        arguments += ["fmu", unzipped, md.coSimulation.modelIdentifier, md.guid,
                      str(len(inputs)), *(str(vr) for _, vr in inputs), str(len(outputs)), *(str(vr) for _, vr in outputs)]
    import sysconfig

    env = dict(os.environ, LD_LIBRARY_PATH=sysconfig.get_config_var("LIBDIR"))
    done = subprocess.run([str(host), str(steps), str(rounds), repr(h), *arguments], capture_output=True, text=True,
                          env=env, timeout=3600)
    if done.returncode != 0:
        raise RuntimeError(f"step_host failed ({done.returncode}): {done.stderr[-2000:]}")
    lines = done.stdout.split("\n")
    return {label: [float(x) for x in line.split()[1:]] for label, line in zip(order, lines)}


class FmpySlave:
    """One FMU under fmpy, initialised, stepped as a Python host does (fmpy's high-level calls)."""

    def __init__(self, fmu: Path, label: str, folder: Path, h: float) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        md = read_model_description(str(fmu), validate=False)
        self.fmi3 = md.fmiVersion.startswith("3")
        kind = FMU3Slave if self.fmi3 else FMU2Slave
        identifier = md.coSimulation.modelIdentifier
        self.slave = kind(guid=md.guid, unzipDirectory=extract(str(fmu), str(folder / f"fmpy-{label}")),
                          modelIdentifier=identifier, instanceName=label)
        inputs, outputs = ports(fmu)
        self.inputs = [vr for _, vr in inputs]
        self.values = list(INPUT_VALUES[:len(inputs)])
        self.outputs = [vr for _, vr in outputs]
        self.h = h
        self.t = 0.0
        if self.fmi3:
            self.slave.instantiate()
            self.slave.enterInitializationMode(startTime=0.0)
        else:
            self.slave.instantiate()
            self.slave.setupExperiment(startTime=0.0)
            self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def timed(self, steps: int) -> float:
        slave, inputs, values, outputs, h, t = self.slave, self.inputs, self.values, self.outputs, self.h, self.t
        set_, get = (slave.setFloat64, slave.getFloat64) if self.fmi3 else (slave.setReal, slave.getReal)
        step = slave.doStep
        began = time.process_time()
        for _ in range(steps):
            set_(inputs, values)
            step(t, h)
            get(outputs)
            t += h
        seconds = time.process_time() - began
        self.t = t
        return seconds / steps


def peer_fmu(n_outputs: int, n_inputs: int, folder: Path) -> Path:
    """A C FMU (tests/cfmus.py) with outputs o0, o1, ... holding `INPUT_VALUES` and inputs x0, x1, ...
    it ignores: the other end of every connection of the FMU under test in cosim."""
    from cfmus import build_c_fmu, fmi2_description

    name = f"Peer{n_outputs}x{n_inputs}"
    variables = [(f"x{j}", j, "input", 0.0) for j in range(n_inputs)]
    variables += [(f"o{k}", 32 + k, "output", None) for k in range(n_outputs)]
    description = fmi2_description(name, variables, {f"o{k}": [] for k in range(n_outputs)},
                                   f"{{00000000-0000-0000-0042-{n_outputs:06d}{n_inputs:06d}}}")
    starts = "".join(f"s->r[{32 + k}] = {INPUT_VALUES[k]!r};" for k in range(n_outputs))
    body = (f"static void start(S *s) {{ {starts} }}\nstatic void calculate(S *s) {{}}\n"
            "static int step(S *s, double t, double h) { return 0; }\n")
    return build_c_fmu(folder, name, description, body)


class CosimRun:
    """One FMU run by cosim's compiled loop, its inputs driven by a C peer's outputs and its outputs
    driving the peer's inputs (`peer_fmu`), only time kept: per step the peer's doStep, get and set
    (in the floor's figure too) and the FMU's set, doStep and get."""

    def __init__(self, fmu: Path, label: str, folder: Path, h: float, steps: int) -> None:
        import cosim
        from ssdgen import ssd_text, write_system

        inputs, outputs = ports(fmu)
        peer = peer_fmu(len(inputs), len(outputs), folder)
        connections = [("peer", f"o{k}", "fmu", name) for k, (name, _) in enumerate(inputs)]
        connections += [("fmu", name, "peer", f"x{j}") for j, (name, _) in enumerate(outputs)]
        components = {"peer": (peer.name, {**{f"o{k}": "output" for k in range(len(inputs))},
                                           **{f"x{j}": "input" for j in range(len(outputs))}}),
                      "fmu": (fmu.name, {**{name: "input" for name, _ in inputs},
                                         **{name: "output" for name, _ in outputs}})}
        system = write_system(folder / f"cosim-{label}", {peer.name: peer, fmu.name: fmu},
                              ssd_text(label, components, connections, stop=steps * h, step=h))
        self.prepared = cosim.prepare(system, use_providers=False)
        self.steps = steps

    def timed(self, steps: int) -> float:
        return loop_cpu(self.prepared) / self.steps


def loop_cpu(prepared) -> float:
    """The CPU seconds of the stepping loop (`cosim.run.execution.Execution.run`) of one cosim run of ``prepared``, only
    time kept; RuntimeError unless every operation ran in the compiled loop."""
    from cosim.run.execution import Execution
    from cosim.run.simulation import run

    spent = []
    original = Execution.run

    def timed_run(execution, *args, **kwargs):
        began = time.process_time()
        try:
            return original(execution, *args, **kwargs)
        finally:
            spent.append(time.process_time() - began)

    Execution.run = timed_run
    try:
        _, meta = run(prepared, keep=[])
    finally:
        Execution.run = original
    if meta.get("kernel") != "native" or meta.get("python_operations"):
        raise RuntimeError(f"cosim did not run every operation in the compiled loop: {meta.get('kernel_reason')}, "
                           f"{meta.get('python_operations')}")
    return spent[0]


def system_loop(args: argparse.Namespace) -> None:
    """``--system DIR``: cosim's loop over the scenario DIR with our FMUs of this tree and with those
    of ``--baseline``, interleaved, µs per step (CPU time of the loop, only time kept)."""
    import cosim
    from greyfmu.build import build_fmus

    ssd = (args.system / "SystemStructure.ssd").read_text()
    names = sorted(set(re.findall(r'source="resources/(\w+)\.fmu"', ssd)))
    with tempfile.TemporaryDirectory(prefix="bench-slave-system-") as temp:
        folder = Path(temp)
        trees = {"ours": build_fmus(names, out_dir=folder / "ours")[0].parent}
        if args.baseline is not None:
            trees["before"] = args.baseline
        for label, fmus in trees.items():
            copy = shutil.copytree(args.system, folder / label / args.system.name)
            (copy / "resources").mkdir(exist_ok=True)
            for name in names:
                shutil.copy(fmus / f"{name}.fmu", copy / "resources" / f"{name}.fmu")
        default = cosim.prepare(folder / "ours" / args.system.name, use_providers=False)
        step = default.grid.step
        default.close()
        prepared = {label: cosim.prepare(folder / label / args.system.name, stop_time=args.steps * step,
                                         use_providers=False) for label in trees}
        us: dict[str, list[float]] = {label: [] for label in trees}
        print(f"{args.system.name}: {', '.join(names)}; {args.steps} steps of {step:g} s, best of {args.rounds}, "
              f"load average {os.getloadavg()[0]:.2f}")
        for _ in range(args.rounds):
            for label in trees:
                us[label].append(loop_cpu(prepared[label]) / args.steps * 1e6)
        for label, values in us.items():
            print(f"  {label:6} {best(values):6.2f} µs/step (median {statistics.median(values):.2f})")
        if "before" in us:
            print(f"  ours / before {best(us['ours']) / best(us['before']):.2f}")
        for run in prepared.values():
            run.close()


# ------------------------------------------------------------------------------------------- report


def best(values: list[float]) -> float:
    return min(values)


def report_host(host: str, us: dict[str, list[float]], advance: float) -> dict[str, float]:
    """The best round of each FMU and what ours (and before) add: to the law on the floor (the law
    FMU), and to the floor and the law alone (``advance``, µs); the target: at most 1.5 law."""
    figures = {label: best(values) for label, values in us.items()}
    law = figures["law"] - figures["floor"]
    print(f"  {host:6} " + "  ".join(f"{label} {figures[label]:6.2f}" for label in LABELS if label in figures)
          + f" µs/step; the law on the floor {law:.2f} µs, alone {advance:.2f} µs")
    for label in ("before", "ours"):
        if label in figures:
            on_floor = figures[label] - figures["law"]
            alone = figures[label] - figures["floor"] - advance
            print(f"         {label:6} adds {on_floor:6.2f} µs = {on_floor / law:5.2f} law to the law on the floor, "
                  f"{alone:6.2f} µs = {alone / advance:5.2f} law to the floor and the law alone; "
                  f"{figures[label] / figures['floor']:4.2f}x the floor")
    return figures


LABELS = ("floor", "law", "ours", "before")
"""The FMUs of a model: pythonfmu's floor, the law on it, ours, ours as built elsewhere (--baseline)."""


def measure(args: argparse.Namespace) -> None:
    from dropinhost import compile_host
    from greyfmu.build import build_fmus

    with tempfile.TemporaryDirectory(prefix="bench-slave-step-") as temp:
        folder = Path(temp)
        ours = {path.stem: path for path in build_fmus(args.fmus, out_dir=folder / "ours")}
        host = compile_host(folder, HOST_SOURCE) if "c" in args.hosts else None
        summary = {}
        print(f"load average before: {os.getloadavg()[0]:.2f}")
        for model in args.fmus:
            fmi3 = floor_variables(ours[model])[0].startswith("3")
            fmus = {"floor": build_floor(ours[model], model, folder / "floor"),
                    "law": build_law(model, fmi3, folder / "law"), "ours": ours[model]}
            if args.baseline is not None and (args.baseline / f"{model}.fmu").is_file():
                fmus["before"] = args.baseline / f"{model}.fmu"
            h = default_step(ours[model])
            law = law_timer(model, h)
            work = folder / model
            work.mkdir(parents=True, exist_ok=True)
            hosts: dict[str, dict[str, list[float]]] = {}
            laws = [law(args.steps) * 1e6 for _ in range(args.rounds)]
            if host is not None and not fmi3:
                hosts["C host"] = c_host(host, fmus, h, args.steps, args.rounds, work)
            for name, make in (("cosim", lambda f, label: CosimRun(f, label, work, h, args.steps)),
                               ("fmpy", lambda f, label: FmpySlave(f, label, work, h))):
                if name not in args.hosts:
                    continue
                runners = {label: make(f, label) for label, f in fmus.items()}
                us = hosts[name] = {label: [] for label in fmus}
                for _ in range(args.rounds):
                    for label, runner in runners.items():
                        us[label].append(runner.timed(args.steps) * 1e6)
                    laws.append(law(args.steps) * 1e6)
            advance = best(laws)
            print(f"\n{model} (step {h:g} s), best of {args.rounds} rounds of {args.steps} steps, CPU time; "
                  f"the law alone (advance in a Python loop) {advance:.2f} µs")
            summary[model] = {"advance": advance, **{name: report_host(name, us, advance) for name, us in hosts.items()}}
        print(f"\nload average after: {os.getloadavg()[0]:.2f}")
        if args.json:
            args.json.write_text(json.dumps(summary, indent=1))


# ------------------------------------------------------------------------------------------ decompose


def decompose(args: argparse.Namespace) -> None:
    """The parts of a step of the slave classes in Python (see the module docstring)."""
    import importlib

    from greyfmu import forwarding
    from greyfmu.build import build_fmus

    with tempfile.TemporaryDirectory(prefix="bench-slave-parts-") as temp:
        folder = Path(temp)
        sys.path.insert(0, str(folder))
        tree = Path(forwarding.__file__).resolve().parents[1]
        print(f"tree {tree}; load average {os.getloadavg()[0]:.2f}; µs, best of {args.rounds} rounds of {args.steps}")
        for fmu in build_fmus(args.fmus, out_dir=folder / "fmus"):
            model = fmu.stem
            cls = slave_class(model)
            ours = cls(instance_name="ours", resources=None)
            write_floor(fmu, model, folder)
            floor = getattr(importlib.import_module(f"{model}Floor"), f"{model}Floor")(instance_name="floor",
                                                                                         resources=None)
            parts = _parts(ours, floor, floor_variables(fmu)[0].startswith("3"), forwarding)
            us = {name: [] for name in parts}
            for _ in range(args.rounds):
                for name, part in parts.items():
                    us[name].append(part(args.steps) * 1e6)
            figures = {name: best(values) for name, values in us.items()}
            step, floor_step = figures["ours set+step+get"], figures["floor set+step+get"]
            print(f"{model}: ours set+step+get {step:.2f}, floor {floor_step:.2f}, law {figures['law']:.2f}, "
                  f"warnings {figures['warnings']:.2f}, accessors (set+get) {figures['ours set+get']:.2f} "
                  f"against {figures['floor set+get']:.2f}, do_step {figures['ours do_step']:.2f}: rest of do_step "
                  f"{figures['ours do_step'] - figures['law'] - figures['warnings'] - figures['floor do_step']:.2f}; "
                  f"ours - floor - law = {step - floor_step - figures['law']:.2f} "
                  f"({(step - floor_step - figures['law']) / figures['law']:.2f} law)")


def _parts(ours, floor, fmi3: bool, forwarding) -> dict:
    """Timers (steps -> CPU s per step) of the parts of a step, of the model's default step."""
    h = (ours.default_experiment or type(ours).default_experiment).step_size  # FMI 2.0: a class attribute
    for name, value in zip(ours._input_names, INPUT_VALUES):
        setattr(ours, name, value)
    ours._ensure_built()
    inputs = [vr for vr, v in ours.vars.items() if v.causality.name == "input"]
    outputs = [vr for vr, v in ours.vars.items() if v.causality.name == "output"]
    values = list(INPUT_VALUES[:len(inputs)])
    get_name, set_name = ("get_float64", "set_float64") if fmi3 else ("get_real", "set_real")
    if hasattr(forwarding, "keep_routing"):
        routing = forwarding.keep_routing

        def warnings_part(steps: int) -> float:
            began = time.process_time()
            for _ in range(steps):
                routing()
            return (time.process_time() - began) / steps
    else:
        def warnings_part(steps: int) -> float:
            began = time.process_time()
            for _ in range(steps):
                with ours.forwarding_warnings():
                    pass
            return (time.process_time() - began) / steps

    def stepper(slave, with_step: bool = True, with_exchange: bool = True):
        clock = {"t": 0.0}
        set_, get, do_step = getattr(slave, set_name), getattr(slave, get_name), slave.do_step

        def timed(steps: int) -> float:
            t = clock["t"]
            began = time.process_time()
            for _ in range(steps):
                if with_exchange:
                    set_(inputs, values)
                if with_step:
                    do_step(t, h)
                if with_exchange:
                    get(outputs)
                t += h
            seconds = time.process_time() - began
            clock["t"] = t
            return seconds / steps

        return timed

    def law(steps: int, clock={"t": 1e6}) -> float:
        t, advance = clock["t"], ours.advance
        began = time.process_time()
        for _ in range(steps):
            advance(t, h)
            t += h
        clock["t"] = t
        return (time.process_time() - began) / steps

    return {"ours set+step+get": stepper(ours), "floor set+step+get": stepper(floor), "law": law,
            "warnings": warnings_part, "ours set+get": stepper(ours, with_step=False),
            "floor set+get": stepper(floor, with_step=False), "ours do_step": stepper(ours, with_exchange=False),
            "floor do_step": stepper(floor, with_exchange=False)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmus", nargs="+", default=["PID", "FOPDT", "GrayPredictivePI", "PID3"])
    parser.add_argument("--baseline", type=Path, help="a folder of FMUs built otherwise (the 'before')")
    parser.add_argument("--hosts", nargs="+", default=["c", "cosim", "fmpy"], choices=["c", "cosim", "fmpy"])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=31)
    parser.add_argument("--json", type=Path, help="write the figures there")
    parser.add_argument("--decompose", action="store_true", help="split a step of the slave classes in Python")
    parser.add_argument("--tree", type=Path, help="with --decompose: the tree whose fmus/ and greyfmu to use")
    parser.add_argument("--system", type=Path, help="cosim's loop over this scenario (e.g. ssp/pid_fopdt), ours "
                                                    "against --baseline")
    args = parser.parse_args()
    tree_on_path(args.tree if args.tree is not None else ROOT)
    if args.decompose:
        decompose(args)
    elif args.system is not None:
        system_loop(args)
    else:
        measure(args)


if __name__ == "__main__":
    main()
