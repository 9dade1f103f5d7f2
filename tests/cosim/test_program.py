"""The step's program from the plan alone (issue 40: `compile_step` needed live instances, although
the program's shape depends on the plan only; its one test instantiated C FMUs): `compile(plan)` is a
value, printed by ``cosim info --program``, built here from a plan whose FMU descriptions are records
written in the test (no FMU file exists), and `link` adds the instances without changing it."""
from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli import main
from cosim.model.fmu import FMUDescription, Variable
from cosim.model.frozen import FrozenMap
from cosim.plan.build import build_plan
from cosim.read import ssp
from cosim.run.program import OP_FEED, OP_GET, OP_MAP, OP_ROUTE, OP_SET, OP_SOLVE, OP_STEP, compile
from ssdgen import ssd_text, write_system

#: source -> gain -> sum (u1), sum.y -> gain2 with a LinearTransformation; lag fed by gain2
COMPONENTS = {"src": ("Src.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"}),
              "lag": ("Lag.fmu", {"u": "input", "y": "output"})}
CONNECTIONS = [("src", "y", "gain", "u", 2.0, 0.5), ("gain", "y", "lag", "u")]


def _description(name: str, variables: list[Variable], dependencies: dict[str, tuple[str, ...]]) -> FMUDescription:
    return FMUDescription(path=Path(f"/nowhere/{name}.fmu"), kind="fmi2-cs", fmi_version="2.0", guid="{x}",
                          generation_tool=None, model_identifier=name,
                          variables=FrozenMap((v.name, v) for v in variables), output_dependencies=FrozenMap(dependencies),
                          unit_definitions=(), default_experiment=None, log_categories=(),
                          instantiated_once_per_process=False, continuous_states=0, event_indicators=0,
                          needs_completed_integrator_step=False)


def _plan(tmp_path):
    """The plan of a system whose FMUs exist only as description records (feedthrough in ``gain``)."""
    folder = write_system(tmp_path / "s", {}, ssd_text("s", COMPONENTS, CONNECTIONS, stop=1.0, step=0.5))
    structure = ssp.load(folder)
    real = dict(type="Real", variability="continuous")
    fmus = {"src": _description("Src", [Variable("y", 1, causality="output", **real)], {"y": ()}),
            "gain": _description("Gain", [Variable("u", 1, causality="input", **real),
                                          Variable("y", 2, causality="output", **real)], {"y": ("u",)}),
            "lag": _description("Lag", [Variable("u", 1, causality="input", **real),
                                        Variable("y", 2, causality="output", **real)], {"y": ()})}
    return build_plan(structure, fmus)


def test_the_program_is_compiled_from_the_plan_alone(tmp_path):
    plan = _plan(tmp_path)
    program = compile(plan)
    assert [(op.kind, op.component) for op in program.ops] == [
        (OP_STEP, "src"), (OP_STEP, "gain"), (OP_STEP, "lag"),           # Jacobi: every doStep
        (OP_GET, "src"), (OP_GET, "lag"),                                 # gain is read in its settling only
        (OP_ROUTE, "gain"), (OP_SET, "gain"), (OP_GET, "gain"),           # the feedthrough settling
        (OP_ROUTE, None), (OP_SET, "lag")]                                # every route; gain set in the settling
    assert program.step_ops == 3 and program == compile(plan) and hash(program) == hash(compile(plan))
    routes = program.ops[8].routes
    assert [plan.routes[i].label for i in routes] == ["src.y -> gain.u", "gain.y -> lag.u"]
    listing = program.listing()
    assert listing[0] == "step program (jacobi): 10 operations, the step 0..2, the exchange 3..9"
    assert "   8 route   all            Real" in listing and "             src.y -> gain.u = 2*src.y + 0.5" in listing
    gauss = compile(plan, "gauss-seidel")
    assert [(op.kind, op.component) for op in gauss.ops[:gauss.step_ops]] == [
        (OP_STEP, "src"), (OP_GET, "src"), (OP_ROUTE, "gain"), (OP_SET, "gain"), (OP_STEP, "gain"), (OP_GET, "gain"),
        (OP_ROUTE, "lag"), (OP_SET, "lag"), (OP_STEP, "lag"), (OP_GET, "lag")]   # upstream first
    assert not any(op.kind in (OP_MAP, OP_FEED, OP_SOLVE) for op in program.ops)


def test_cosim_info_prints_the_program(tmp_path, twin_fmus, capsys):
    components = {"lag": ("FirstOrderFilter.fmu", {"y": "output", "u": "input"}), "step": ("Step.fmu", {"y": "output"}),
                  "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
    files = {f: twin_fmus[f.removesuffix(".fmu")] for f, _ in components.values()}
    folder = write_system(tmp_path / "chain", files, ssd_text("chain", components, [("step", "y", "gain", "u", 2.0, 0.5),
                                                                                    ("gain", "y", "lag", "u")]))
    assert main(["info", str(folder), "--program"]) == 0
    out = capsys.readouterr().out.splitlines()
    start = out.index("step program (jacobi): 10 operations, the step 0..2, the exchange 3..9")
    assert out[start + 1:start + 4] == ["   0 doStep  lag", "   1 doStep  step", "   2 doStep  gain"]
    assert main(["info", str(folder), "--program", "--algorithm", "gauss-seidel"]) == 0
    assert "step program (gauss-seidel)" in capsys.readouterr().out


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_link_keeps_the_program_s_operations(tmp_path, twin_fmus, algorithm):
    """The live operations are the program's, one for one, in its order (`cosim.run.link`)."""
    from cosim.plan.prepare import prepare
    from cosim.run.execution import Execution

    components = {"step": ("Step.fmu", {"y": "output"}), "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
    files = {f: twin_fmus[f.removesuffix(".fmu")] for f, _ in components.values()}
    folder = write_system(tmp_path / "s", files, ssd_text("s", components, [("step", "y", "gain", "u")]))
    with prepare(folder, use_providers=False, algorithm=algorithm) as prepared:
        program = compile(prepared.plan, algorithm)
        execution = Execution(prepared.plan, prepared.grid, algorithm)
        try:
            execution.instantiate()
            linked = execution.link(program)
        finally:
            execution.close()
    assert linked.program is program
    assert [(op.kind, op.component, op.type_name, op.at_step_end, op.next) for op in linked.operations] == \
        [(op.kind, op.component, op.type_name, op.at_step_end, op.next) for op in program.ops]
