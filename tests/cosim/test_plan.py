"""The Plan as the one product of validation (cosim.plan.build, cosim.plan.prepare.prepare and
resolve_grid): built from small real FMUs (the C twins of greyfmu's Step, Gain and
FirstOrderFilter, tests/twin_fmus.py), changing nothing it is given, and holding everything a
run, a pack and a sweep need."""
from __future__ import annotations

import copy
import dataclasses
import pickle
import zipfile

import numpy as np
import pytest

from cosim.read import ssp
from cosim.errors import SetupError
from cosim.present.pack import pack
from cosim.plan.parameters import check_values
from cosim.plan.build import build_plan
from cosim.model.transforms import Affine
from cosim.read.resources import locate_fmus
from cosim.model.frozen import FrozenMap
from cosim.plan.prepare import prepare, resolve_grid
from cosim.read.description import describe_fmus
from cosim.run.simulation import run
from cosim.model.structure import ParameterValue, Plan
from ssdgen import ssd_text, write_system

COMPONENTS = {"lag": ("FirstOrderFilter.fmu", {"y": "output", "u": "input"}),
              "step": ("Step.fmu", {"y": "output"}),
              "gain": ("Gain.fmu", {"u": "input", "y": "output"})}
CONNECTIONS = [("step", "y", "gain", "u", 2.0, 0.5), ("gain", "y", "lag", "u")]


@pytest.fixture
def chain(tmp_path, twin_fmus):
    """step -> (x2 + 0.5) -> gain (k = 3) -> lag; the SSD lists lag first."""
    text = ssd_text("chain", COMPONENTS, CONNECTIONS, stop=2.0, step=0.1,
                    parameters={"step": {"t_step": 0.5}, "gain": {"k": 3.0}, "lag": {"T": 0.2}})
    files = {f: twin_fmus[f.removesuffix(".fmu")] for f, _ in COMPONENTS.values()}
    return write_system(tmp_path / "chain", files, text)


def test_locating_and_planning_change_nothing_they_are_given(chain):
    structure = ssp.load(chain)
    before = copy.deepcopy(structure)
    fmu_paths = locate_fmus(structure, use_providers=False)
    assert fmu_paths == {name: chain / "resources" / fmu for name, (fmu, _) in COMPONENTS.items()}
    extra = [ParameterValue("gain.k", "Real", 4.0, "cli.ssv", 3)]
    plan = build_plan(structure, describe_fmus(structure, fmu_paths), extra)
    assert structure == before and extra == [ParameterValue("gain.k", "Real", 4.0, "cli.ssv", 3)]
    assert {f"{s.component}.{s.variable.name}": s.value for s in plan.start_values}["gain.k"] == 4.0


def test_each_fmu_file_is_described_and_checked_once(tmp_path, twin_fmus, monkeypatch):
    """Issue 42: 40 gains of one FMU file are located, described and checked once (per component,
    it was 1.2 ms a component at N = 1000), each component getting that description."""
    import cosim.read.description as description

    components = {f"g{i}": ("Gain.fmu", {"u": "input", "y": "output"}) for i in range(40)}
    components["step"] = ("Step.fmu", {"y": "output"})
    folder = write_system(tmp_path / "gains", {"Gain.fmu": twin_fmus["Gain"], "Step.fmu": twin_fmus["Step"]},
                          ssd_text("gains", components, [("step", "y", f"g{i}", "u") for i in range(40)]))
    import cosim.read.resources as resources

    structure = ssp.load(folder)
    described, real = [], description.describe_fmu
    monkeypatch.setattr(description, "describe_fmu",
                        lambda path, *args: described.append(path.name) or real(path, *args))
    located, locate = [], resources._locate
    monkeypatch.setattr(resources, "_locate", lambda comp, *args: located.append(comp.source) or locate(comp, *args))
    descriptions = describe_fmus(structure, locate_fmus(structure, use_providers=False))
    assert sorted(described) == ["Gain.fmu", "Step.fmu"] and len(located) == 2
    assert len({id(descriptions[f"g{i}"]) for i in range(40)}) == 1 and descriptions["g7"].model_identifier == "Gain"


def validate(path) -> Plan:
    """The plan of ``path`` (a folder: its files stay where they are)."""
    with prepare(path, use_providers=False, grid_placeholders=True) as prepared:
        return prepared.plan


def test_a_plan_is_plain_data_that_round_trips_through_pickle(chain, tmp_path):
    """No fmpy object in a plan (cosim.read.description's records); an unpickled copy equals it, and a
    copy of an .ssp's run reads the archive's extracted files without owning them (a sweep ships
    runs to its workers this way, cosim.sweep.dispatch.Task.prepared)."""
    plan = validate(chain)
    data = pickle.dumps(plan)
    assert b"fmpy" not in data and pickle.loads(data) == plan and hash(pickle.loads(data)) == hash(plan)
    packed = prepare(pack(plan, tmp_path / "chain.ssp"), use_providers=False)
    try:
        shipped = pickle.loads(pickle.dumps(packed))
        assert shipped == packed and shipped.owner is None
        shipped.close()   # the copy owns no folder: the files stay for the run that extracted them
        assert packed.plan.files.base_dir.is_dir()
        assert run(shipped)[0].tobytes() == run(packed)[0].tobytes()
    finally:
        packed.close()
    assert not packed.plan.files.base_dir.exists()


def test_a_plan_is_frozen_all_the_way_down_and_hashable(chain):
    """Issue 40: on the pid_fopdt plan ``plan.routes.append(...)`` was accepted and ``hash(plan)``
    failed (15 fields were lists, dicts or sets); an FMU description added to its own dicts when
    an FMI 3.0 array element was looked up.  Now every field is a tuple, a frozenset, a FrozenMap
    or a frozen record, down to the descriptions' variables, and the plan holds no structure."""
    plan = validate(chain)
    assert isinstance(hash(plan), int) and not hasattr(plan, "structure")
    with pytest.raises(AttributeError):
        plan.routes.append(plan.routes[0])
    with pytest.raises(TypeError):
        plan.fmus["lag"] = plan.fmus["gain"]
    with pytest.raises(TypeError):
        plan.fmus["gain"].variables["k"] = None
    with pytest.raises(AttributeError):
        plan.read_in_settling_only.add("lag")

    def walk(value, where: str):
        if isinstance(value, (list, dict, set, bytearray, np.ndarray)):
            raise AssertionError(f"{where} is a mutable {type(value).__name__}")
        if dataclasses.is_dataclass(value):
            assert value.__dataclass_params__.frozen, f"{where} ({type(value).__name__}) is not frozen"
            for f in dataclasses.fields(value):
                walk(getattr(value, f.name), f"{where}.{f.name}")
        elif isinstance(value, FrozenMap):
            for k, v in value.items():
                walk(v, f"{where}[{k!r}]")
        elif isinstance(value, (tuple, frozenset)):
            for i, v in enumerate(value):
                walk(v, f"{where}[{i}]")
    walk(plan, "plan")


def test_the_plan_holds_routes_columns_units_and_the_experiment(chain):
    plan = validate(chain)
    assert [(r.src, r.src_var.name, r.dst, r.dst_var.name, r.transform) for r in plan.routes] == [
        ("step", "y", "gain", "u", Affine(2.0, 0.5)), ("gain", "y", "lag", "u", Affine(1.0, 0.0))]
    assert plan.columns == ("lag.y", "lag.u", "step.y", "gain.u", "gain.y")  # SSD order, as declared
    assert plan.recorded() == (["lag.y", "step.y", "gain.y"], ["lag.u", "gain.u"])
    assert set(plan.units) == set(plan.columns) and plan.solvers == {} and plan.system_outputs == {}
    assert (plan.experiment.stop_time, plan.experiment.step_size) == (2.0, 0.1)
    assert plan.files.source == chain / "SystemStructure.ssd" and plan.name == "chain"
    assert plan.feedthrough_sequence == ("gain",) and plan.gauss_seidel_order == ("step", "gain", "lag")


def test_run_and_pack_need_nothing_but_the_plan(chain, tmp_path):
    """The plan alone, its scenario closed, runs and packs."""
    plan = validate(chain)
    result, meta = run(resolve_grid(plan))
    archive = pack(plan, tmp_path / "chain.ssp")
    assert meta["status"] == "completed" and list(result.dtype.names) == ["time", *plan.columns]
    after = result["time"] >= 0.6 - 1e-12   # the step (t = 0.5) is seen by the next communication point
    assert np.allclose(result["gain.u"][after], 2.5) and np.allclose(result["gain.y"][after], 7.5)
    with zipfile.ZipFile(archive) as z:
        assert sorted(z.namelist()) == ["SystemStructure.ssd", "resources/FirstOrderFilter.fmu",
                                        "resources/Gain.fmu", "resources/Step.fmu"]


def test_resolve_grid_takes_the_arguments_then_the_ssd(chain):
    plan = validate(chain)
    prepared = resolve_grid(plan)
    assert (prepared.grid.stop, prepared.grid.step, prepared.algorithm) == (2.0, 0.1, "jacobi")
    assert prepared.step_source == "annotation org.greyfmu.simulation"
    prepared = resolve_grid(plan, step_size=0.5, stop_time=1.0, algorithm="gauss-seidel")
    assert (prepared.grid.step, prepared.step_source, prepared.grid.steps) == (0.5, "command line", 2)
    with pytest.raises(SetupError, match="unknown algorithm 'euler'"):
        resolve_grid(plan, algorithm="euler")
    with pytest.raises(SetupError, match="the step size must be a positive number"):
        resolve_grid(plan, step_size=-1.0)


def test_resolve_grid_refuses_what_the_ssd_does_not_give(tmp_path, twin_fmus):
    text = ssd_text("nostep", {"step": ("Step.fmu", {"y": "output"})}, [], step=None)
    plan = validate(write_system(tmp_path / "nostep", {"Step.fmu": twin_fmus["Step"]}, text))
    assert plan.experiment.step_size is None
    with pytest.raises(SetupError, match="no step size: pass --step"):
        resolve_grid(plan)
    assert resolve_grid(plan, step_size=0.25).grid.steps == 4


def test_check_values_gives_the_masters_messages_without_a_second_plan(chain):
    plan = validate(chain)
    check_values(plan, [ParameterValue("gain.k", "Real", 5.0, "sweep", 0)])
    with pytest.raises(SetupError, match="the FMU Gain.fmu has no variable 'kk'"):
        check_values(plan, [ParameterValue("gain.kk", "Real", 5.0, "sweep", 0)])
    with pytest.raises(SetupError, match="does not start with a component name"):
        check_values(plan, [ParameterValue("nothing.k", "Real", 5.0, "sweep", 0)])
    with pytest.raises(SetupError, match="causality 'output'"):
        check_values(plan, [ParameterValue("gain.y", "Real", 5.0, "sweep", 0)])


def test_looking_up_an_array_element_leaves_the_description_as_it_was():
    """Issue 40: `FMUDescription.variable` added an FMI 3.0 array element to the description's own
    dicts (and to its output dependencies), on the copy a module cache shared with every later
    plan.  Now the lookup returns the element and changes nothing; `with_elements` returns a new
    description that knows it."""
    from pathlib import Path

    from cosim.model.fmu import ArrayElement, FMUDescription, Variable

    array = Variable("x", 7, "Float64", "input", "continuous", dimensions=(3,))
    out = Variable("y", 8, "Float64", "output", "continuous")
    desc = FMUDescription(Path("/nowhere/A.fmu"), "fmi3-cs", "3.0", "{g}", None, "A",
                          FrozenMap({"x": array, "y": out}), FrozenMap({"y": ("x",)}), (), None, (), False, 0, 0,
                          False)
    element = desc.variable("x[2]", "here", "x.ssd")
    assert isinstance(element, ArrayElement) and (element.index, element.vr) == (1, 0xFFFFFFFF)
    assert desc.elements == {} and desc.output_dependencies == {"y": ("x",)} and isinstance(hash(desc), int)
    known = desc.with_elements([element])
    assert known.elements == {0xFFFFFFFF: element} and known.output_dependencies == {"y": ("x", "x[2]")}
    assert known.variable("x[2]", "here", "x.ssd") is element and desc.elements == {}
    assert known.variable("x[3]", "here", "x.ssd").vr == 0xFFFFFFFE   # the next free reference


def test_the_elements_of_a_large_array_resolve_in_one_pass():
    """Issue 41: a whole array's connector resolves all its elements at once (`FMUDescription.resolve`):
    one by one, 4000 elements took 9.7 s (each lookup and each new description copied all the
    elements before it; 10 000 about a minute), 10 000 now take 0.3 s.  Value references are
    distinct and free, an input element joins the inputs an output depends on, an output element
    gets its array's."""
    from pathlib import Path

    from cosim.model.fmu import FMUDescription, Variable, element_names

    u = Variable("u", 1, "Float64", "input", "continuous", dimensions=(100, 100))
    y = Variable("y", 0xFFFFFFFF - 5, "Float64", "output", "continuous", dimensions=(2,))
    desc = FMUDescription(Path("/nowhere/A.fmu"), "fmi3-cs", "3.0", "{g}", None, "A",
                          FrozenMap({"u": u, "y": y}), FrozenMap({"y": ("u",)}), (), None, (), False, 0, 0, False)
    names = element_names("u", (100, 100)) + ["y[2]"]
    known, variables = desc.resolve(names, "here", "x.ssd")
    vrs = [v.vr for v in variables]
    assert len(set(vrs)) == len(names) == len(known.elements) and y.vr not in vrs and 1 not in vrs
    assert variables[101].name == "u[2,2]" and variables[101].index == 101
    assert known.output_dependencies["y[2]"] == known.output_dependencies["y"] == ("u", *names[:-1])
    assert known.resolve(["u[2,2]"], "here", "x.ssd")[1][0] is variables[101]


def test_start_values_are_typed_before_the_plan_which_is_built_once(chain, monkeypatch):
    """Issue 40: with --start-value the plan was built twice (once to type the values); the
    descriptions type them now, and `cosim.simulate` takes them as `cosim run` does."""
    import cosim
    import cosim.plan.prepare

    built = []
    plan = cosim.plan.prepare.build_plan
    monkeypatch.setattr(cosim.plan.prepare, "build_plan", lambda *a, **kw: built.append(1) or plan(*a, **kw))
    result = cosim.simulate(chain, start_values={"gain.k": 4.0, "step.t_step": 0.2}, use_providers=False)
    assert built == [1] and result["gain.y"][-1] == 4.0 * 2.5
