"""The compiled stepping loop (issue 19, `cosim.kernel`) against the Python loop: the same
samples bit for bit (NaN-aware), the same statuses, messages and metadata, on C FMUs
compiled here (tests/cfmus.py: feedthrough chains with factor/offset routes, Integer and
Boolean exchange, Gauss–Seidel, FMI 2.0 and 3.0, a Discard, terminateSimulation, an Error, a
signal raised by an FMU mid-run, a crash with the journal on) and on every scenario of ssp/
(pythonfmu FMUs) with a short stop; and the fallback: refusals of --kernel native, and the
Python loop with one notice when the library cannot be loaded."""
from __future__ import annotations

import ctypes
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cfmus import build_c_fmu
from cosim.errors import SetupError
from cosim.run.interrupts import stop_on_signals
from cosim.kernel import ABI_VERSION, _Program, library
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from runhelpers import assert_same, run_kernel as _run
from ssdgen import ssd_text, write_system
from cosim.kernel import library
from peers import gemseo_fmu_dir

ROOT = Path(__file__).parents[2]
pytestmark = pytest.mark.skipif(library()[0] is None, reason=f"no compiled kernel: {library()[1]}")

#: a block: y = gain*u + x (direct feedthrough), x' = u - x, m = n + steps, bo = !bi; at t >=
#: fail_time the step returns fail_status (asking to terminate when terminate = 1, ending at
#: t + h/2 when halfway = 1), and at t >= signal_time it raises SIGTERM once
BLOCK_BODY = r"""
#include <signal.h>
static void start(S *s) { s->r[3] = 0.5; s->r[4] = 1e9; s->r[5] = 0; s->r[6] = 0; s->r[7] = 0; s->r[8] = 1e9; }
static void calculate(S *s) {
    s->r[1] = s->r[3] * s->r[0] + s->r[2]; s->i[IM] = s->i[IN] + (int) s->l[0]; s->b[1] = !s->b[0]; }
static int step(S *s, double t, double h) {
    s->r[2] += h * (s->r[0] - s->r[2]); s->l[0] += 1;
    if (t >= s->r[8] && !s->l[1]) { s->l[1] = 1; raise(SIGTERM); }
    if (t >= s->r[4]) {
        if (s->r[6] != 0) s->terminate = 1;
        if (s->r[7] != 0) s->last = t + h / 2;
        return (int) s->r[5]; }
    return 0; }
"""

PARAMETERS = ["gain", "fail_time", "fail_status", "terminate", "halfway", "signal_time"]

BLOCK2 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Block" guid="{19c0de00-0000-4000-8000-000000000019}">
  <CoSimulation modelIdentifier="Block" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input" variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output" variability="continuous"><Real/></ScalarVariable>
    <ScalarVariable name="x" valueReference="2" causality="output" variability="continuous"><Real/></ScalarVariable>
""" + "".join(f"""    <ScalarVariable name="{p}" valueReference="{3 + i}" causality="parameter" variability="fixed" initial="exact"><Real start="{s}"/></ScalarVariable>
""" for i, (p, s) in enumerate(zip(PARAMETERS, ["0.5", "1e9", "0", "0", "0", "1e9"]))) + """\
    <ScalarVariable name="n" valueReference="0" causality="input" variability="discrete"><Integer start="0"/></ScalarVariable>
    <ScalarVariable name="m" valueReference="1" causality="output" variability="discrete"><Integer/></ScalarVariable>
    <ScalarVariable name="bi" valueReference="0" causality="input" variability="discrete"><Boolean start="false"/></ScalarVariable>
    <ScalarVariable name="bo" valueReference="1" causality="output" variability="discrete"><Boolean/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs>
    <Unknown index="2" dependencies="1"/><Unknown index="3" dependencies=""/>
    <Unknown index="11" dependencies="10"/><Unknown index="13" dependencies="12"/>
  </Outputs></ModelStructure>
</fmiModelDescription>
"""

BLOCK3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Block3" instantiationToken="{19c0de00-0000-4000-8000-000000000193}">
  <CoSimulation modelIdentifier="Block3" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="63" causality="independent" variability="continuous"/>
    <Float64 name="u" valueReference="0" causality="input" variability="continuous" start="0"/>
    <Float64 name="y" valueReference="1" causality="output" variability="continuous"/>
    <Float64 name="x" valueReference="2" causality="output" variability="continuous"/>
""" + "".join(f"""    <Float64 name="{p}" valueReference="{3 + i}" causality="parameter" variability="fixed" start="{s}"/>
""" for i, (p, s) in enumerate(zip(PARAMETERS, ["0.5", "1e9", "0", "0", "0", "1e9"]))) + """\
    <Int32 name="n" valueReference="10" causality="input" variability="discrete" start="0"/>
    <Int32 name="m" valueReference="11" causality="output" variability="discrete"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1" dependencies="0"/><Output valueReference="2" dependencies=""/>
    <Output valueReference="11" dependencies="10"/>
  </ModelStructure>
</fmiModelDescription>
"""

#: the same block with a Boolean (a C bool in FMI 3.0, exchanged through the master's conversion)
BOOLEAN3 = BLOCK3.replace("Block3", "Bool3").replace("000000000193", "000000000194").replace(
    '    <Int32 name="n"', '    <Boolean name="bi" valueReference="20" causality="input" variability="discrete" start="false"/>\n'
                          '    <Int32 name="n"')


@pytest.fixture(scope="module")
def blocks(tmp_path_factory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("blocks")
    return {"Block": build_c_fmu(tmp, "Block", BLOCK2, "#define IN 0\n#define IM 1\n" + BLOCK_BODY, "2.0"),
            "Block3": build_c_fmu(tmp, "Block3", BLOCK3, "#define IN 10\n#define IM 11\n" + BLOCK_BODY, "3.0"),
            "Bool3": build_c_fmu(tmp, "Bool3", BOOLEAN3, "#define IN 10\n#define IM 11\n" + BLOCK_BODY, "3.0")}


def _chain(tmp_path: Path, blocks: dict, kinds: list[str], parameters: dict | None = None, stop: float = 50.0,
           step: float = 0.01) -> Path:
    """Blocks b0 -> b1 -> ... (5000 steps by default: more than a chunk of the recorder, and
    kernel calls of 25 steps between progress updates; y -> u with factors and offsets, m -> n, bo -> bi between FMI 2.0
    blocks); b0's u is fed back from the last block's x (no feedthrough: no algebraic loop)."""
    comps, connections = {}, []
    for i, kind in enumerate(kinds):
        connectors = {"u": "input", "y": "output", "x": "output", "n": "input", "m": "output"}
        if kind == "Block":
            connectors |= {"bi": "input", "bo": "output"}
        if kind == "Bool3":
            connectors["bi"] = "input"
        comps[f"b{i}"] = (f"{kind}.fmu", connectors)
        if i:
            connections += [(f"b{i - 1}", "y", f"b{i}", "u", 1.5 + i, -0.25 * i), (f"b{i - 1}", "m", f"b{i}", "n")]
            if kind == "Block" and kinds[i - 1] == "Block":
                connections.append((f"b{i - 1}", "bo", f"b{i}", "bi"))
    connections.append((f"b{len(kinds) - 1}", "x", "b0", "u", 0.1, 1.0))
    params = {f"b{i}": {"gain": 0.5 + 0.1 * i} for i in range(len(kinds))}
    for comp, values in (parameters or {}).items():
        params[comp] |= values
    fmus = {f"{k}.fmu": blocks[k] for k in set(kinds)}
    return write_system(tmp_path / "sys", fmus, ssd_text("chain", comps, connections, stop=stop, step=step,
                                                         parameters=params))






def _both(folder: Path, **kw) -> tuple[tuple, tuple]:
    python, compiled = _run(folder, "python", **kw), _run(folder, "native", **kw)
    assert python[1]["kernel"] == "python" and compiled[1]["kernel"] == "native"
    assert_same(python[0], compiled[0])
    for key in ("status", "message", "last_time"):
        assert python[1][key] == compiled[1][key], key
    assert python[2] == compiled[2]
    return python, compiled


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
@pytest.mark.parametrize("kinds", [["Block"] * 4, ["Block3"] * 3, ["Block", "Block3", "Block", "Block3"]])
def test_chains_run_bit_identical(tmp_path, blocks, kinds, algorithm):
    """Feedthrough settled in order, factor/offset routes, Integer and Boolean exchange."""
    python, compiled = _both(_chain(tmp_path, blocks, kinds), algorithm=algorithm)
    result = compiled[0]
    assert len(result) == 5001 and compiled[1]["status"] == "completed"
    last = f"b{len(kinds) - 1}"
    assert result[f"{last}.m"][-1] == 5000 * len(kinds)  # the steps added up along the Integer chain
    assert np.ptp(result[f"{last}.y"]) > 0.1  # the values moved


@pytest.mark.parametrize("kind", ["Block", "Block3"])
@pytest.mark.parametrize("terminate, halfway, status", [(1, 0, "terminated"), (0, 1, "discarded"),
                                                        (1, 1, "discarded")])
def test_discard_and_terminate_end_the_run_as_in_python(tmp_path, blocks, kind, terminate, halfway, status):
    """b1 ends the run at t = 1 (Discard, or FMI 3.0 OK with terminateSimulation): recorded
    there when its outputs are valid at the end of the step, else the run ends at the last good
    time; b2, after b1 in the stepping order, still steps in that last step."""
    fail = {"fail_time": 0.985, "fail_status": 0 if kind == "Block3" and terminate and not halfway else 2,
            "terminate": terminate, "halfway": halfway}
    python, compiled = _both(_chain(tmp_path, blocks, [kind] * 3, {"b1": fail}))
    assert compiled[1]["status"] == status
    assert compiled[0]["time"][-1] == pytest.approx(1.0 if status == "terminated" else 0.99)


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_an_error_status_fails_the_run_as_in_python(tmp_path, blocks, algorithm):
    folder = _chain(tmp_path, blocks, ["Block", "Block3", "Block"], {"b1": {"fail_time": 0.5, "fail_status": 3}})
    python, compiled = _both(folder, algorithm=algorithm)
    assert compiled[1]["status"] == "failed" and "fmi3DoStep returned Error at t = 0.5" in compiled[2]
    assert compiled[0]["time"][-1] == pytest.approx(0.5)


def test_a_warning_goes_on(tmp_path, blocks):
    python, compiled = _both(_chain(tmp_path, blocks, ["Block"] * 2, {"b0": {"fail_time": 0.5, "fail_status": 1}}))
    assert compiled[1]["status"] == "completed" and len(compiled[0]) == 5001


def test_a_signal_during_a_native_call_stops_at_that_communication_point(tmp_path, blocks):
    """An FMU raises SIGTERM inside fmi2DoStep at t = 0.7 (after the chunk began): the compiled
    loop sees it through its own handler and stops after recording t = 0.71, as Python does."""
    folder = _chain(tmp_path, blocks, ["Block"] * 3, {"b2": {"signal_time": 0.695}})
    results = {}
    for kernel in ("python", "native"):
        prepared = prepare(folder)
        try:
            with stop_on_signals() as stop:
                results[kernel] = run(prepared, kernel=kernel, stop=stop)
        finally:
            prepared.close()
    assert_same(results["python"][0], results["native"][0])
    meta = results["native"][1]
    assert meta["status"] == results["python"][1]["status"] == "interrupted"
    assert meta["message"] == results["python"][1]["message"] == "stopped by SIGTERM at t = 0.71."


def test_a_crash_with_the_journal_loses_no_row_in_either_loop(tmp_path, blocks):
    """A C FMU that aborts at t = 1 in `cosim run` (its supervisor recovers the journal): the
    same rows, every one recorded before the crash, from both loops."""
    body = BLOCK_BODY.replace("if (t >= s->r[8]", "if (t >= s->r[4]) abort();\n    if (t >= s->r[8]")
    abort_fmu = build_c_fmu(tmp_path / "fmu", "Block", BLOCK2, "#define IN 0\n#define IM 1\n#include <stdlib.h>\n"
                            + body, "2.0")
    folder = _chain(tmp_path, {"Block": abort_fmu}, ["Block"] * 2, {"b1": {"fail_time": 0.985}})
    rows = {}
    for kernel in ("python", "native"):
        out = tmp_path / f"crash_{kernel}.csv"
        proc = subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(folder), "-q", "-o", str(out),
                               "--kernel", kernel], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 1 and "SIGABRT" in proc.stderr, proc.stderr
        assert json.loads(out.with_suffix(".json").read_text())["status"] == "crashed"
        rows[kernel] = out.read_text()
    assert rows["python"] == rows["native"] and len(rows["native"].splitlines()) == 1 + 100  # header, t = 0..0.99


def test_what_c_cannot_call_python_makes_within_the_compiled_loop(tmp_path, blocks):
    """A C bool in FMI 3.0 goes through the master's conversion: the compiled loop hands b0's
    Boolean sets back to Python at every step and makes the rest itself (auto and native alike);
    the same samples as the Python loop, and the metadata counts what Python made and why."""
    folder = _chain(tmp_path, blocks, ["Bool3", "Block3"], stop=0.1)
    python, compiled = _both(folder)
    auto = _run(folder, "auto")
    assert_same(python[0], auto[0])
    why = "component 'b0' exchanges Boolean values through the master's FMI 3.0 conversion"
    for meta in (compiled[1], auto[1]):
        assert meta["kernel"] == "native" and list(meta["python_operations"]) == [why], meta
    assert "python_operations" not in python[1] and "kernel_reason" not in python[1]


def test_without_the_library_auto_runs_python_with_one_notice(tmp_path, blocks):
    folder = _chain(tmp_path, blocks, ["Block"] * 2, stop=0.1)
    script = (f"import warnings, cosim\nfrom cosim.plan.prepare import prepare\nfrom cosim.run.simulation import run\n"
              f"warnings.simplefilter('always')\n"
              f"for _ in range(2):\n"
              f"    p = prepare({str(folder)!r})\n"
              f"    result, meta = run(p)\n"
              f"    p.close()\n"
              f"    print(meta['kernel'], '|', meta['kernel_reason'], '|', len(result))\n")
    env = dict(os.environ, COSIM_KERNEL_LIBRARY=str(tmp_path / "missing.so"))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 2 and all(line.startswith("python | the compiled kernel ") and "missing.so cannot be "
                                   "loaded" in line and line.endswith("| 11") for line in lines), lines
    assert proc.stderr.count("running the Python stepping loop") == 1, proc.stderr


def _stale_library(tmp_path: Path, name: str, source: str, *flags: str) -> Path:
    """kernel.c as edited (``source``) and compiled here: a library out of step with the ctypes mirrors."""
    c_file, library_file = tmp_path / f"{name}.c", tmp_path / f"{name}.so"
    c_file.write_text(source)
    subprocess.run(["cc", "-shared", "-fPIC", "-O1", "-pthread", *flags, "-o", str(library_file), str(c_file)],
                   check=True)
    return library_file


@pytest.mark.parametrize("edit, expected", [
    ("version", rf"ABI version {ABI_VERSION + 1}, expected {ABI_VERSION}"),
    ("field", rf"sizeof\(Program\) is {ctypes.sizeof(_Program) + 8} bytes in C, {ctypes.sizeof(_Program)} in ctypes"),
    ("no abi", r"it has no cosim_kernel_abi")])
def test_a_stale_library_is_refused_by_its_abi(tmp_path, blocks, monkeypatch, edit, expected):
    """A kernel library whose structures differ from the ctypes mirrors (a _kernel*.so left from
    before an edit of kernel.c) is not used: auto runs Python and says why, native refuses."""
    source = (ROOT / "cosim" / "kernel" / "kernel.c").read_text()
    if edit == "field":
        source = source.replace("    long long steps;\n} Program;", "    long long steps;\n    double added;\n} Program;")
    if edit == "no abi":
        source = source.replace("int cosim_kernel_abi(", "int cosim_kernel_no_abi(")
    stale = _stale_library(tmp_path, edit.replace(" ", "_"), source,
                           *([f"-DKERNEL_ABI_VERSION={ABI_VERSION + 1}"] if edit == "version" else []))
    folder = _chain(tmp_path, blocks, ["Block"] * 2, stop=0.1)
    monkeypatch.setenv("COSIM_KERNEL_LIBRARY", str(stale))
    library.cache_clear()
    try:
        assert library()[0] is None and re.search(expected, library()[1]), library()[1]
        with pytest.raises(SetupError, match=f"compiled kernel cannot run this system: the compiled kernel "
                                             f"{re.escape(str(stale))} does not match .*{expected}"):
            _run(folder, "native")
        result, meta, _ = _run(folder, "auto")
        assert meta["kernel"] == "python" and re.search(expected, meta["kernel_reason"]) and len(result) == 11
    finally:
        monkeypatch.delenv("COSIM_KERNEL_LIBRARY")
        library.cache_clear()
    assert library()[0] is not None, library()[1]


@pytest.mark.parametrize("parameters", [{}, {"b1": {"fail_time": 0.985, "fail_status": 2, "terminate": 1}},
                                        {"b2": {"fail_time": 0.5, "fail_status": 3}}])
def test_threads_step_in_parallel_bit_identical(tmp_path, blocks, parameters):
    """--threads 2: the doSteps of a Jacobi step on two threads; the same samples, statuses and
    messages as the Python loop (a component after one that ended the step has stepped too)."""
    folder = _chain(tmp_path, blocks, ["Block", "Block3", "Block", "Block3"], parameters, stop=5.0)
    python, threaded = _run(folder, "python"), _run(folder, "native", threads=2)
    assert_same(python[0], threaded[0])
    for key in ("status", "message", "last_time"):
        assert python[1][key] == threaded[1][key], key
    assert python[2] == threaded[2]
    assert threaded[1]["threads"] == 2 and threaded[1]["parallel_components"] == ["b0", "b1", "b2", "b3"]


def test_the_flush_deadline_returns_to_python_at_every_row(tmp_path, blocks, monkeypatch):
    """flush_seconds = 0: the kernel's clock says a flush is due after every row, so each row
    reaches the sinks on its own, as the Python loop's `Recorder.record` does."""
    import cosim.run.simulation
    from cosim.record.observers import Recorder

    flushes = {}

    class Counting(Recorder):
        def __init__(self, *args, **kw):
            super().__init__(*args, **kw, flush_seconds=0.0)
            self.flushes = flushes.setdefault(len(flushes), [0])

        def flush(self):
            self.flushes[0] += 1
            super().flush()

    monkeypatch.setattr(cosim.run.simulation, "Recorder", Counting)
    folder = _chain(tmp_path, blocks, ["Block"] * 2, stop=0.5)
    python, compiled = _both(folder)
    assert flushes[0][0] == flushes[1][0] >= 50  # one per row (and the last at closing)


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_the_step_is_one_program_both_interpreters_run(tmp_path, blocks, algorithm):
    """`cosim.run.program.compile` from the plan: Jacobi's doSteps first, or Gauss–Seidel's routes,
    sets, doStep and gets per component in dependency order; then the exchange (gets, the settling
    of the feedthrough chain, the routes, the sets).  Linked to live C FMUs (`cosim.run.link`),
    every operation has a C form, FMI 3.0 doSteps a post-step."""
    from cosim.run.execution import Execution
    from cosim.run.program import OP_GET, OP_ROUTE, OP_SET, OP_STEP, compile

    prepared = prepare(_chain(tmp_path, blocks, ["Block", "Block3", "Block"], stop=0.1), algorithm=algorithm)
    program = compile(prepared.plan, algorithm)
    step = [(op.kind, op.component) for op in program.ops[:program.step_ops]]
    if algorithm == "jacobi":
        assert step == [(OP_STEP, "b0"), (OP_STEP, "b1"), (OP_STEP, "b2")]
    else:
        order = prepared.plan.gauss_seidel_order
        assert [c for kind, c in step if kind == OP_STEP] == list(order)
        for comp in order:  # its inputs before its doStep, its outputs after
            kinds = [kind for kind, c in step if c == comp]
            assert kinds.index(OP_STEP) > kinds.index(OP_SET) and kinds[-1] == OP_GET
    exchange = [op.kind for op in program.ops[program.step_ops:]]
    assert exchange[0] == OP_GET and exchange[-1] == OP_SET and OP_ROUTE in exchange
    assert program.top_level() == list(range(len(program.ops)))
    execution = Execution(prepared.plan, prepared.grid, algorithm)
    try:
        execution.instantiate()
        linked = execution.link(program)
        assert [(op.kind, op.component, op.type_name) for op in linked.operations] == \
            [(op.kind, op.component, op.type_name) for op in program.ops]
        assert all(op.native is not None for op in linked.operations) and linked.python_operations() == {}
        assert [op.component for op in linked.operations if op.post_step is not None] == ["b1"]   # fmi3DoStep's out-arguments
        assert execution.choice.name == "native"
    finally:
        execution.close()
        prepared.close()


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


ALL_SCENARIOS = sorted(p.parent.name for p in (ROOT / "ssp").glob("*/SystemStructure.ssd"))


FAMILIES = {"btg_boiler_following", "dpi_wood_berry", "grey_sim33", "gs_sim2_1", "osmm_mfrls", "pid_fopdt",
            "pid_mass_damper", "pid_mass_damper_me", "sopdt_nmp", "units_demo"}


SCENARIOS = ALL_SCENARIOS if os.environ.get("COSIM_KERNEL_SCENARIOS") == "all" else \
    [s for s in ALL_SCENARIOS if s in FAMILIES]


@pytest.mark.pythonfmu
def test_the_default_scenarios_exist():
    assert FAMILIES <= set(ALL_SCENARIOS)


@pytest.mark.pythonfmu
@pytest.mark.parametrize("scenario, parameter_sets", [(s, ()) for s in SCENARIOS]
                         + [("pid_fopdt", ("pi_only.ssv",)), ("grey_sim33", ("ph40.ssv",))])
def test_scenarios_run_the_same_in_both_loops(scenario, parameter_sets):
    """A scenario of ssp/ (pythonfmu FMUs, and OpenModelica's from gemseo-fmu) for 100 steps,
    both loops, sample by sample."""
    folder, fmu_dirs = ROOT / "ssp" / scenario, [gemseo_fmu_dir()]
    sets = [folder / p for p in parameter_sets]
    step = prepare(folder, fmu_dirs=fmu_dirs)
    try:
        stop = step.grid.start + 100 * step.grid.step
    finally:
        step.close()
    results = {}
    for kernel in ("python", "auto"):
        prepared = prepare(folder, stop_time=stop, fmu_dirs=fmu_dirs, parameter_sets=sets)
        try:
            results[kernel] = run(prepared, kernel=kernel)
        finally:
            prepared.close()
    assert_same(results["python"][0], results["auto"][0])
    meta = results["auto"][1]
    kinds = {c["interface"] for c in meta["components"].values()}
    assert meta["kernel"] == "native", meta.get("kernel_reason")
    in_python = " ".join(meta.get("python_operations", {}))
    assert ("Model Exchange" in in_python) == bool(kinds - {"fmi2-cs", "fmi3-cs"})
    assert ("algebraic loop" in in_python) == ((meta["algebraic_loops"] or {}).get("mode") == "iterate")


@pytest.mark.pythonfmu
def test_threads_keep_pythonfmu_components_serial_and_refuse_gauss_seidel(tmp_path):
    folder = ROOT / "ssp" / "pid_fopdt"
    python, threaded = _run(folder, "python", tmp_path), None
    prepared = prepare(folder, stop_time=1.0)
    try:
        threaded = run(prepared, threads=2)
        with pytest.raises(SetupError, match=r"--threads 2 steps components in parallel within a Jacobi step"):
            run(prepare(folder, stop_time=1.0, algorithm="gauss-seidel"), threads=2)
    finally:
        prepared.close()
    assert threaded[1]["parallel_components"] == []
    assert all("pythonfmu FMU" in why for why in threaded[1]["serial_components"].values())
    assert_same(threaded[0], python[0][:len(threaded[0])])
