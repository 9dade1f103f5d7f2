"""The compiled get/set of fmus/_slave.py (GreyfmuSlave) against pythonfmu 0.7.0's generic
Fmi2Slave get/set: same values and Python types for every variable of every FMU of fmus/, the
same refusals, and the parameters' setter side effects (rebuild, retune) still happen.

The slaves are exercised in-process (the Python objects pythonfmu's C++ wrapper calls) and,
for the wrapper itself, through two real FMUs loaded by fmpy: benchmarks/fmus/Exchange.py
(compiled) and ExchangeGeneric.py (the same FMU with the generic methods).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from pythonfmu import Fmi2Causality, Fmi2Slave, Integer, Real

from greyfmu.build import FMU_SOURCES, slave_class

ROOT = Path(__file__).resolve().parents[2]
FMI2_SLAVES = sorted(path.stem for path in FMU_SOURCES.glob("*.py") if not path.name.startswith("_"))
"""The FMUs built on fmus/_slave.py (each also the FMI 3.0 <Name>3.fmu, fmus/fmi3/_slave3.py)."""
GENERIC = {Real: (Fmi2Slave.get_real, Fmi2Slave.set_real), Integer: (Fmi2Slave.get_integer, Fmi2Slave.set_integer)}


@pytest.fixture(scope="module", autouse=True)
def _slave_sources_importable():
    sys.path.insert(0, str(FMU_SOURCES))
    yield
    sys.path.remove(str(FMU_SOURCES))


def slave_pair(name: str) -> tuple[Fmi2Slave, Fmi2Slave]:
    cls = slave_class(FMU_SOURCES / f"{name}.py")
    return cls(instance_name=f"{name}_compiled"), cls(instance_name=f"{name}_generic")


def compiled(slave: Fmi2Slave, kind: type) -> tuple:
    return {Real: (slave.get_real, slave.set_real), Integer: (slave.get_integer, slave.set_integer)}[kind]


def exact(values: list) -> list[str]:
    """Values compared bit for bit, with their Python type (1 and 1.0 differ; NaN equals NaN)."""
    return [f"{type(v).__name__}:{v!r}" for v in values]


def assert_same_reads(fast: Fmi2Slave, generic: Fmi2Slave) -> None:
    for kind, (generic_get, _) in GENERIC.items():
        vrs = [vr for vr, v in fast.vars.items() if isinstance(v, kind)]
        get = compiled(fast, kind)[0]
        for batch in (vrs, vrs[::-1], *([vr] for vr in vrs)):
            assert exact(get(batch)) == exact(generic_get(generic, batch)), (fast.instance_name, kind, batch)


@pytest.mark.parametrize("name", FMI2_SLAVES)
def test_compiled_exchange_matches_the_generic_one(name):
    fast, generic = slave_pair(name)
    assert_same_reads(fast, generic)  # before setup: start values, outputs from a first build
    for slave in (fast, generic):
        slave.setup_experiment(0.0)
        slave.enter_initialization_mode()
    # every parameter set back to its value (through the setters: marks a rebuild), every input moved
    for kind, (generic_get, generic_set) in GENERIC.items():
        get, set_ = compiled(fast, kind)
        parameters = [vr for vr, v in fast.vars.items() if isinstance(v, kind) and v.causality == Fmi2Causality.parameter]
        inputs = [vr for vr, v in fast.vars.items() if isinstance(v, kind) and v.causality == Fmi2Causality.input]
        values = get(parameters)
        set_(parameters, values)
        generic_set(generic, parameters, values)
        moved = [v + 0.125 for v in get(inputs)]
        set_(inputs, moved)
        generic_set(generic, inputs, moved)
        if inputs:
            set_(inputs[:1], moved[:1])  # a single-input list: its own compiled writer
            generic_set(generic, inputs[:1], moved[:1])
    assert_same_reads(fast, generic)
    for slave in (fast, generic):
        slave.exit_initialization_mode()
    assert fast.do_step(0.0, 0.5) == generic.do_step(0.0, 0.5)
    assert_same_reads(fast, generic)


def test_unknown_value_references_and_wrong_types_are_refused_as_by_the_generic_path():
    fast, generic = slave_pair("FirstOrderFilter")
    vr = {v.name: ref for ref, v in fast.vars.items()}
    unknown = max(vr.values()) + 1
    cases = [
        (lambda s: s.get_real([vr["u"], unknown]), lambda s: Fmi2Slave.get_real(s, [vr["u"], unknown]), KeyError),
        (lambda s: s.set_real([unknown], [1.0]), lambda s: Fmi2Slave.set_real(s, [unknown], [1.0]), KeyError),
        (lambda s: s.get_integer([vr["y"]]), lambda s: Fmi2Slave.get_integer(s, [vr["y"]]), TypeError),
        (lambda s: s.get_boolean([vr["K"]]), lambda s: Fmi2Slave.get_boolean(s, [vr["K"]]), TypeError),
        (lambda s: s.set_real([vr["y"]], [1.0]), lambda s: Fmi2Slave.set_real(s, [vr["y"]], [1.0]), TypeError),
    ]
    for call_fast, call_generic, error in cases:
        with pytest.raises(error) as refused:
            call_fast(fast)
        with pytest.raises(error):
            call_generic(generic)
        assert "FirstOrderFilter_compiled" in str(refused.value)
    with pytest.raises(KeyError, match=f"value reference {unknown}"):
        fast.get_real([unknown])  # a refused list is not cached: refused again
    assert fast.get_real([vr["u"]]) == [0.0]


def test_a_fixed_parameter_set_after_the_build_rebuilds_the_objects():
    fast, _ = slave_pair("FirstOrderFilter")
    vr = {v.name: ref for ref, v in fast.vars.items()}
    fast.setup_experiment(0.0)
    fast.exit_initialization_mode()
    built = fast.lag
    fast.set_real([vr["K"], vr["u"]], [2.0, 1.0])  # a parameter and an input in one call
    assert fast.get_real([vr["y"]]) == [0.0]
    assert fast.lag is not built and fast.lag.K == 2.0
    assert fast.do_step(0.0, 0.5)
    assert fast.get_real([vr["y"]]) == [2.0 * (1.0 - math.exp(-0.5))]


def test_a_tunable_parameter_is_retuned_and_an_invalid_value_refused_with_a_warning():
    fast, _ = slave_pair("SOPDTPredictive")
    vr = {v.name: ref for ref, v in fast.vars.items()}
    fast.setup_experiment(0.0)
    fast.exit_initialization_mode()
    controller = fast.controller
    fast.set_real([vr["X_p"]], [0.3])
    assert fast.controller is controller and controller.X_p == 0.3 and fast.X_p == 0.3
    fast.log_queue.clear()
    fast.set_real([vr["X_p"]], [5.0])
    assert controller.X_p == 0.3 and fast.get_real([vr["X_p"]]) == [0.3]
    assert any("X_p stays 0.3" in message.msg for message in fast.log_queue)


# ------------------------------------------------------------------ through pythonfmu's C++ wrapper


@pytest.fixture(scope="module")
def exchange_fmus(tmp_path_factory) -> dict[str, Path]:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from bench_exchange import build
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return build(tmp_path_factory.mktemp("exchange"))


BATCHED = textwrap.dedent(
    """
    import ctypes, json, math, os, sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(sys.argv[1])
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(sys.argv[1]),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=md.modelName)
    slave.instantiate(loggingOn=False)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    raw = slave._functions
    values = [math.pi * (i + 1) ** 3 for i in range(16)]
    inputs = (ctypes.c_uint * 16)(*[vr[f"u{i}"] for i in range(1, 17)])
    answer = {"set": raw["fmi2SetReal"](slave.component, inputs, 16, (ctypes.c_double * 16)(*values))}
    for n in (1, 4, 16):
        outputs = (ctypes.c_uint * n)(*[vr[f"y{i}"] for i in range(n, 0, -1)])
        read = (ctypes.c_double * n)()
        answer[f"status{n}"] = raw["fmi2GetReal"](slave.component, outputs, n, read)
        answer[str(n)] = [v.hex() for v in read]
    unknown = (ctypes.c_uint * 1)(len(vr) + 7)
    answer["unknown"] = raw["fmi2GetReal"](slave.component, unknown, 1, (ctypes.c_double * 1)())
    print(json.dumps(answer), flush=True)
    os._exit(0)  # not Python's finalization: see below
    """
)
"""One FMU through pythonfmu's C++ wrapper, in a process of its own: these FMUs are plain pythonfmu
0.7.0 builds, without the greyfmu loader that balances the slave module's namespace (see
tests/slaves/test_pythonfmu_references.py), so each instantiation releases that dict once more than
it owns; in the pytest process the dict of ExchangeGeneric was freed under its module and the final
garbage collection segfaulted (2 of 4 full runs, exit 139 after every test had passed).  In a
process of its own the same over-release still aborts that process's finalization now and then
("corrupted double-linked list", exit -6 after the answer was printed: 2 of 2 runs of tests/slaves
after the sweep tests, 0 of 120 alone), so the script leaves by os._exit once its answer is out."""


def test_the_fmus_answer_batched_calls_alike_and_refuse_an_unknown_reference(exchange_fmus):
    values = [math.pi * (i + 1) ** 3 for i in range(16)]
    answers = {}
    for kind, path in exchange_fmus.items():
        run = subprocess.run([sys.executable, "-c", BATCHED, str(path)], capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, (kind, run.returncode, run.stderr[-2000:])
        answers[kind] = json.loads(run.stdout.strip().splitlines()[-1])
        # after fmi2Fatal no other call is allowed (FMI 2.0 §2.1.3): the instance is left as it is
    assert answers["fast"] == answers["generic"]
    assert [answers["fast"][f"status{n}"] for n in (1, 4, 16)] == [0, 0, 0] and answers["fast"]["set"] == 0
    assert [float.fromhex(v) for v in answers["fast"]["16"]] == values[::-1]
    assert answers["fast"]["unknown"] == answers["generic"]["unknown"] == 4  # fmi2Fatal: pythonfmu's answer to an exception
