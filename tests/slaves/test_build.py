"""greyfmu build: the FMUs validate, declare the agreed interface and simulate correctly."""

import dataclasses
import html
import math
import os
import shutil
import subprocess
import sys
import zipfile
from importlib.metadata import version
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from greyfmu.build import (
    FMU_SOURCES,
    BuildError,
    UnknownFmuError,
    _rewrite_model_description,
    build_fmus,
    fmu_names,
    provide_fmu,
    slave_class,
)
from greyfmu.cli import main
from greyfmu.dropin import BUILD_PYTHON, GUARD, MAX_STEP_FACTOR, stable_guid
from greyfmu.privatise import PRIVATE_PACKAGE, PYTHONFMU
import greyfmu.loader
from greyfmu.loader import PLATFORMS, loader_binary
from testfmus import edited_copy

INTERFACE = {
    # name: (parameters, inputs, outputs -> same-instant input dependencies)
    "PID": (
        ["Kc", "Ti", "Td", "N", "Ts", "anti_windup", "derivative_on", "form", "u_min", "u_max", "du_max", "integral_mode",
         "u0"],
        ["r", "y"],
        {"u": [], "e": []},
    ),
    "FOPDT": (["K", "T", "tau", "y0"], ["u", "d"], {"y": []}),
    "Step": (["t_step", "initial", "final"], [], {"y": []}),
    "Ramp": (["start_time", "slope", "initial", "final"], [], {"y": []}),
    "Pulse": (["amplitude", "start_time", "width", "period", "offset"], [], {"y": []}),
    "BandLimitedWhiteNoise": (["power", "Ts", "seed"], [], {"y": []}),
    "FirstOrderFilter": (["K", "T", "y0"], ["u"], {"y": []}),
    "Sum": (["k1", "k2", "k3"], ["u1", "u2", "u3"], {"y": ["u1", "u2", "u3"]}),
    "Gain": (["k"], ["u"], {"y": ["u"]}),
}
TIME_PARAMETERS = {"Ti", "Td", "Ts", "T", "tau", "t_step", "start_time", "width", "period"}


def variables_by_causality(model_description, causality):
    return [v for v in model_description.modelVariables if v.causality == causality]


ALL = fmu_names()


def test_every_fmu_is_built(built_fmus):
    assert sorted(built_fmus) == ALL
    assert set(INTERFACE) <= set(ALL)


@pytest.mark.parametrize("name", ALL)
def test_fmu_passes_fmpy_validation(built_fmus, name):
    assert validate_fmu(str(built_fmus[name])) == []


@pytest.mark.parametrize("name", ALL)
def test_fmu_follows_the_conventions(built_fmus, name):
    """design.md §3: FMI 2.0 CS without an execution tool, a DefaultExperiment, the requirements
    in the description, a description on every variable, outputs initial="exact" with a start."""
    md = read_model_description(str(built_fmus[name]))
    assert md.fmiVersion == "2.0" and md.coSimulation.needsExecutionTool is False
    assert md.defaultExperiment.stopTime is not None and md.defaultExperiment.stepSize is not None
    assert "Requires Python 3.10+ with numpy and scipy" in md.description
    for variable in md.modelVariables:
        assert variable.description, variable.name
    for output in variables_by_causality(md, "output"):
        assert output.initial == "exact" and output.start is not None, output.name


@pytest.mark.parametrize("name", sorted(INTERFACE))
def test_fmu_declares_the_agreed_interface(built_fmus, name):
    parameters, inputs, dependencies = INTERFACE[name]
    md = read_model_description(str(built_fmus[name]))
    assert [v.name for v in variables_by_causality(md, "parameter")] == parameters
    assert [v.name for v in variables_by_causality(md, "input")] == inputs
    assert [v.name for v in variables_by_causality(md, "output")] == list(dependencies)
    for variable in md.modelVariables:
        assert (variable.unit == "s") == (variable.name in TIME_PARAMETERS), variable.name


@pytest.mark.parametrize("name", ALL)
def test_output_dependencies_are_written_as_the_slave_declares_them(built_fmus, name, monkeypatch):
    md = read_model_description(str(built_fmus[name]))
    declared = slave_class(FMU_SOURCES / f"{name}.py").output_dependencies
    assert {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs} == declared
    if name in INTERFACE:
        assert declared == INTERFACE[name][2]


def test_default_parameters_are_simulation_2_1_at_the_low_operating_point(built_fmus):
    def starts(name):
        md = read_model_description(str(built_fmus[name]))
        return {v.name: float(v.start) for v in variables_by_causality(md, "parameter")}

    assert {k: starts("FOPDT")[k] for k in ("K", "T", "tau")} == {"K": 0.2, "T": 20.0, "tau": 4.0}
    pid = starts("PID")
    assert pid["Kc"] == pytest.approx(1.6069 / 0.2, abs=1e-12)
    assert (pid["Ti"], pid["Td"], pid["N"], pid["Ts"], pid["integral_mode"]) == (7.1713, 1.5363, 10.0, 0.1, 3.0)
    assert (pid["u_min"], pid["u_max"], pid["du_max"], pid["u0"]) == (-1e10, 1e10, 0.0, 0.0)


def test_second_build_skips_everything(built_fmus):
    before = {name: path.stat().st_mtime_ns for name, path in built_fmus.items()}
    lines = []
    paths = build_fmus(echo=lines.append)
    assert paths == [built_fmus[name] for name in fmu_names()]
    assert len(lines) == len(paths) and all("up to date" in line for line in lines)
    assert {path.stem: path.stat().st_mtime_ns for path in paths} == before


@pytest.mark.parametrize("name", ALL)
def test_fmu_simulates_from_its_default_experiment(built_fmus, name):
    md = read_model_description(str(built_fmus[name]))
    result = simulate_fmu(str(built_fmus[name]))
    assert result["time"][-1] == pytest.approx(float(md.defaultExperiment.stopTime))
    for output in variables_by_causality(md, "output"):
        assert np.all(np.isfinite(result[output.name])), output.name


@pytest.mark.parametrize("name", ALL)
def test_fmu_runs_in_a_fresh_python_with_only_its_embedded_greyfmu(built_fmus, tmp_path, name):
    """`fmpy simulate` in another process, outside the repository: each FMU is self-contained,
    computing with the greyfmu it embeds (under its private package), never a public greyfmu.
    No workaround for pythonfmu 0.7.0's double release at unload: the FMU's loader neutralises it."""
    script = ("import sys, fmpy\nfmpy.simulate_fmu(sys.argv[1])\nassert 'greyfmu' not in sys.modules\n"
              "print([module.__file__ for name, module in sys.modules.items() if name.endswith('.greyfmu')])\n")
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    completed = subprocess.run(
        [sys.executable, "-c", script, str(built_fmus[name])],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert completed.returncode == 0, completed.stderr
    assert "resources" in completed.stdout


@pytest.mark.parametrize("step_size", [0.1, 0.3, 0.7])
def test_fopdt_fmu_reproduces_the_analytic_step_response(built_fmus, step_size):
    K, T, tau, y0, t_step, u0, u1 = 0.2, 20.0, 4.0, 0.5, 1.0, 2.5, 4.0
    signal = np.array(
        [(0.0, u0, 0.0), (t_step, u0, 0.0), (t_step, u1, 0.0), (60.0, u1, 0.0)],
        dtype=[("time", float), ("u", float), ("d", float)],
    )
    result = simulate_fmu(
        str(built_fmus["FOPDT"]),
        stop_time=60.0,
        step_size=step_size,
        output_interval=step_size,
        start_values={"y0": y0},
        input=signal,
    )
    t = result["time"]
    elapsed = np.maximum(t - t_step - tau, 0.0)
    expected = y0 + K * (u1 - u0) * -np.expm1(-elapsed / T)
    assert np.max(np.abs(result["y"] - expected)) < 1e-12


def test_pid_fmu_gives_the_p_plus_i_output_and_holds_it_between_samples(built_fmus):
    Kc, Ti, Ts, u0 = 8.0345, 7.1713, 0.1, 0.2
    result = simulate_fmu(
        str(built_fmus["PID"]),
        stop_time=1.0,
        step_size=0.025,
        output_interval=0.025,
        start_values={"r": 1.0, "y": 0.25, "u0": u0},
    )
    e = 0.75
    for t, u, error in zip(result["time"], result["u"], result["e"]):
        samples_taken = math.ceil(t / Ts - 1e-9)  # sample instants in [0, t)
        if samples_taken == 0:
            assert (u, error) == (u0, 0.0)
        else:
            assert u == pytest.approx(u0 + Kc * e * (1 + samples_taken * Ts / Ti), abs=1e-12)
            assert error == e


def instantiate(fmu_path, tmp_path, start_time=0.0, **parameters):
    md = read_model_description(str(fmu_path))
    unzipped = tmp_path / fmu_path.stem
    shutil.unpack_archive(fmu_path, unzipped, "zip")
    fmu = FMU2Slave(
        guid=md.guid, unzipDirectory=str(unzipped), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="test"
    )
    fmu.instantiate(loggingOn=True)
    fmu.setupExperiment(startTime=start_time)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    fmu.enterInitializationMode()
    for name, value in parameters.items():
        fmu.setReal([refs[name]], [value])
    return fmu, refs


def test_source_output_after_initialisation_uses_the_set_parameters_and_start_time(built_fmus, tmp_path):
    fmu, refs = instantiate(built_fmus["Step"], tmp_path, start_time=5.0, t_step=5.0, initial=-1.0, final=2.0)
    assert fmu.getReal([refs["y"]]) == [2.0]  # already in initialisation mode
    fmu.exitInitializationMode()
    assert fmu.getReal([refs["y"]]) == [2.0]
    fmu.terminate()
    fmu.freeInstance()


def test_sum_is_direct_feedthrough(built_fmus, tmp_path):
    fmu, refs = instantiate(built_fmus["Sum"], tmp_path, k2=-1.0)
    fmu.exitInitializationMode()
    fmu.setReal([refs["u1"], refs["u2"], refs["u3"]], [3.0, 1.0, 0.5])
    assert fmu.getReal([refs["y"]]) == [2.5]
    fmu.terminate()
    fmu.freeInstance()


def test_non_finite_input_is_an_error_naming_the_variable(built_fmus, tmp_path, capsys):
    fmu, refs = instantiate(built_fmus["PID"], tmp_path)
    fmu.exitInitializationMode()
    fmu.doStep(0.0, 0.1)
    fmu.setReal([refs["r"]], [math.nan])
    with pytest.raises(Exception, match="fmi2DoStep"):
        fmu.doStep(0.1, 0.1)
    assert "input r = nan" in capsys.readouterr().out
    fmu.freeInstance()


def test_fmu_provider_for_the_master_returns_our_fmus_only(built_fmus):
    assert provide_fmu("FOPDT.fmu") == built_fmus["FOPDT"]
    assert provide_fmu("Mass_Damper.fmu") is None
    assert provide_fmu("FOPDT") is None


def test_unknown_fmu_name_is_refused_with_the_near_ones(capsys):
    assert main(["build", "Xyzzy"]) == 2
    message = capsys.readouterr().err
    assert "unknown FMU Xyzzy;" in message and "`greyfmu info` lists the 26 FMUs, each also as FMI 3.0 <Name>3" in message
    assert main(["build", "FOPTD"]) == 2   # issue 45: the near name, not all 27
    assert "unknown FMU FOPTD (did you mean FOPDT" in capsys.readouterr().err
    with pytest.raises(UnknownFmuError):
        build_fmus(["NoSuchFmu"])


def test_cli_reports_each_fmu_and_the_output_folder(built_fmus, capsys):
    assert main(["build", "Gain", "Sum"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("Gain: up to date") and lines[1].startswith("Sum: up to date")
    assert str(built_fmus["Gain"].parent) in lines[2]


def _declaring(output_dependencies: dict[str, list[str]]) -> type:
    """A slave class as the rewrite reads it: its output dependencies and requirements."""
    return type("Slave", (), {"output_dependencies": output_dependencies, "requirements": ("numpy", "scipy")})


def test_rewrite_refuses_an_output_without_a_declared_dependency_list(built_fmus, tmp_path):
    with pytest.raises(BuildError, match="output_dependencies"):
        _rewrite_model_description(built_fmus["Gain"], tmp_path / "Gain.fmu", _declaring({}), fmi3=False)


def test_rewrite_refuses_an_output_without_initial_exact(built_fmus, tmp_path):
    broken = edited_copy(built_fmus["Gain"], tmp_path / "broken.fmu", lambda xml: xml.replace('initial="exact"', ""))
    with pytest.raises(BuildError, match="initial"):
        _rewrite_model_description(broken, tmp_path / "Gain.fmu", _declaring({"y": ["u"]}), fmi3=False)


def test_rebuilding_gives_a_byte_identical_model_description_and_the_same_guid(built_fmus, tmp_path):
    """Issue 13, stable identity: two builds of unchanged sources; the GUID is not pythonfmu's random one."""
    first, second = (build_fmus(["PID", "OSMMGPC"], tmp_path / folder, force=True) for folder in ("a", "b"))
    for a, b, name in zip(first, second, ["PID", "OSMMGPC"]):
        with zipfile.ZipFile(a) as one, zipfile.ZipFile(b) as other, zipfile.ZipFile(built_fmus[name]) as kept:
            assert one.read("modelDescription.xml") == other.read("modelDescription.xml") \
                == kept.read("modelDescription.xml")
            extra = sorted(n for n in one.namelist() if n.startswith("extra/"))   # the reference experiment (issue 43)
            assert len(extra) == 4 and all(one.read(n) == other.read(n) for n in extra)
    assert read_model_description(str(first[0])).guid != read_model_description(str(first[1])).guid


def test_the_guid_follows_the_model_description_and_every_embedded_source(built_fmus):
    with zipfile.ZipFile(built_fmus["Gain"]) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    root = ElementTree.fromstring(entries["modelDescription.xml"])
    assert stable_guid(root, entries) == root.get("guid")
    (arithmetic,) = [name for name in entries if name.endswith("/greyfmu/signals/arithmetic.py")]
    edited = dict(entries, **{arithmetic: entries[arithmetic] + b"\n"})
    assert stable_guid(root, edited) != root.get("guid")
    assert stable_guid(root, dict(entries, **{BUILD_PYTHON: b"/elsewhere/python3\n"})) == root.get("guid")
    root.find("DefaultExperiment").set("stopTime", "99")
    assert stable_guid(root, entries) != root.get("guid")


@pytest.mark.parametrize("name", ALL)
def test_the_guard_file_lists_the_guid_and_every_variable_as_the_model_description(built_fmus, name):
    """resources/greyfmu_guard.txt (what the loader's guard checks calls against) agrees with
    modelDescription.xml, with FMI 2.0's default initial where a variable states none; it is
    left out of the GUID's hash (it holds the GUID)."""
    with zipfile.ZipFile(built_fmus[name]) as archive:
        lines = archive.read(GUARD).decode().splitlines()
        entries = {entry: archive.read(entry) for entry in archive.namelist()}
    md = read_model_description(str(built_fmus[name]))
    assert lines[:2] == [f"guid {md.guid}", f"max_step {MAX_STEP_FACTOR * float(md.defaultExperiment.stepSize)!r}"]
    letters = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B", "String": "S"}
    defaults = {"parameter": "exact", "input": "none"}  # FMI 2.0 §2.2.7; an input has no initial
    root = ElementTree.fromstring(entries["modelDescription.xml"])
    declared = {node.get("name"): node.get("initial") for node in root.iter("ScalarVariable")}
    expected = [f"variable {v.valueReference} {letters[v.type]} {v.causality} {v.variability} "
                f"{declared[v.name] or defaults.get(v.causality, 'calculated')} {v.name}" for v in md.modelVariables]
    assert lines[2:] == expected
    assert {line.split()[5] for line in lines[2:]} <= {"exact", "calculated", "none"}
    assert stable_guid(root, dict(entries, **{GUARD: b"guid other\n"})) == md.guid


@pytest.mark.parametrize("name", ["PID", "OSMMGPC", "SteamHeader"])
def test_fmu_states_version_licence_and_carries_the_notices_and_documentation(built_fmus, name):
    md = read_model_description(str(built_fmus[name]))
    assert md.version == version("greyfmu") and md.license == "MIT" and md.author == "greyfmu"
    assert "greyfmu authors" in md.copyright and "pythonfmu" in md.copyright
    with zipfile.ZipFile(built_fmus[name]) as archive:
        names = archive.namelist()
        notice = archive.read("documentation/licenses/pythonfmu-LICENSE.txt").decode()
        page = archive.read("documentation/index.html").decode()
    assert "MIT License" in notice and "NTNU" in notice and "documentation/licenses/greyfmu-LICENSE.txt" in names
    for variable in md.modelVariables:  # every variable, with its unit, on the page
        assert f"<td>{html.escape(variable.name)}</td>" in page
        if variable.unit:
            assert f"<td>{html.escape(variable.unit)}</td>" in page
    assert md.defaultExperiment.stopTime in page and "GREYFMU_PYTHON" in page
    if name == "OSMMGPC":
        assert "<code>daqp</code>" in page


@pytest.mark.parametrize("name", ["PID", "OSMMGPC"])
def test_fmu_carries_only_what_it_runs(built_fmus, name):
    """No greyfmu build tooling and no pythonfmu builder: pythonfmu's run-time modules only, and
    all the FMU's Python under its private package (greyfmu.privatise)."""
    with zipfile.ZipFile(built_fmus[name]) as archive:
        names = set(archive.namelist())
        module = archive.read("resources/slavemodule.txt").decode()
    package, _, model = module.partition(".")
    assert PRIVATE_PACKAGE.fullmatch(package) and package.startswith(f"_greyfmu_{name}_") and model == name
    python = {entry for entry in names if entry.startswith("resources/") and entry.endswith(".py")}
    assert {entry for entry in python if not entry.startswith(f"resources/{package}/")} == {
        "resources/greyfmu_target.py", f"resources/{module}.py"}
    assert {entry for entry in names if entry.startswith(f"resources/{package}/pythonfmu/")} == {
        f"resources/{package}/pythonfmu/{runtime}" for runtime in PYTHONFMU.modules}
    assert {f"resources/{package}/{entry}.py" for entry in (name, "_slave", "_inprocess", "_state")} <= names
    build_side = {f"resources/{package}/greyfmu/{entry}" for entry in
                  ("build.py", "cli.py", "dropin.py", "documentation.py", "privatise.py", "lsref.py", "catalogue.py",
                   "names.py", "wiring.py", "fmi3.py")}
    assert not names & build_side
    assert not any(entry.startswith((f"resources/{package}/greyfmu/loader/", f"resources/{package}/greyfmu/licenses/"))
                   for entry in names)
    assert {"binaries/linux64/pythonfmu-export.so", f"binaries/linux64/{name}.so",
            "binaries/linux64/greyfmu-process.so"} <= names


def test_without_a_compiler_for_this_platform_the_build_says_so_and_keeps_pythonfmus_library(capsys):
    missing = dataclasses.replace(PLATFORMS[0], compilers=("no-such-cc",))
    assert loader_binary(missing) is None
    assert "no C compiler for linux64 (no-such-cc) on PATH: the FMUs keep pythonfmu's linux64 library" \
        in capsys.readouterr().err


def test_a_compiler_warning_fails_the_loader_build_only_in_our_ci(tmp_path, monkeypatch):
    """Issue 29: -Werror only under GREYFMU_WERROR=1 (.ci/run): a user's newer compiler adding a
    warning still builds the loader."""
    import greyfmu.loader

    warned = tmp_path / "warned.c"
    warned.write_text("int unused_argument(int a, int b) { return a; }\n")
    monkeypatch.setattr(greyfmu.loader, "LOADER_SOURCE", warned)
    build = loader_binary.__wrapped__  # not the per-process cache
    monkeypatch.delenv("GREYFMU_WERROR", raising=False)
    assert build(PLATFORMS[0])
    monkeypatch.setenv("GREYFMU_WERROR", "1")
    with pytest.raises(greyfmu.loader.LoaderError, match="unused parameter"):
        build(PLATFORMS[0])


def test_without_mingw_a_linux_build_says_nothing_of_windows_unless_asked(capsys, monkeypatch, tmp_path):
    """Issue 27: a Linux user without mingw-w64 did not ask about Windows: the on-demand build
    (as a first ``cosim run`` does it) says nothing; ``greyfmu build``, asked for the FMUs
    themselves, says it in one short line."""
    missing = dataclasses.replace(PLATFORMS[1], compilers=("no-such-mingw-gcc",))
    assert loader_binary(missing) is None
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(greyfmu.loader, "PLATFORMS", (PLATFORMS[0], missing))
    assert main(["build", "--out", str(tmp_path), "Gain"]) == 0
    err = capsys.readouterr().err
    assert err == "greyfmu build: no no-such-mingw-gcc on PATH: the FMUs' win64 binary is pythonfmu's " \
        "(needs Python on that host)\n"


def test_a_host_with_an_fmus_resources_on_sys_path_still_imports_pythonfmus_builder(built_fmus, tmp_path):
    """A host that keeps an FMU's resources/ on sys.path (and processes spawned from it) imports
    greyfmu's FMU provider and pythonfmu.builder: they must be the installed ones after the FMU
    ran in that process, since everything the FMU embeds is under its private package."""
    shutil.unpack_archive(built_fmus["PID"], tmp_path, "zip")
    script = (f"import sys, fmpy; sys.path.insert(0, {str(tmp_path / 'resources')!r}); "
              f"fmpy.simulate_fmu({str(built_fmus['PID'])!r}, stop_time=0.2); "
              "import pythonfmu.builder, greyfmu.build; print(pythonfmu.__file__); print(greyfmu.__file__)")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
    for installed in completed.stdout.splitlines()[-2:]:
        assert "resources" not in installed, installed


def test_a_process_that_ran_an_fmu_still_builds_from_the_sources(built_fmus, tmp_path):
    """An FMU of ours run in a process leaves no public _slave or slave module there (its code is
    under its private package): a later build in that process (greyfmu's provider during a cosim
    run) reads fmus/."""
    script = (f"import sys, fmpy; fmpy.simulate_fmu({str(built_fmus['Gain'])!r}, stop_time=0.2); "
              "assert not {'_slave', 'Gain', 'pythonfmu'} & set(sys.modules), sorted(sys.modules); "
              "from greyfmu.build import build_fmus; "
              f"print(build_fmus(['Gain'], out_dir={str(tmp_path)!r}, force=True))")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
    assert (tmp_path / "Gain.fmu").is_file()
