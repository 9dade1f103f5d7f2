"""Issue 39: our FMUs together in one process — with each other, with other releases of ours, with
other vendors' Python FMUs of the same names, with the host's own packages — and never silent.

Every host here has no greyfmu: a Python with only fmpy, numpy, scipy and daqp (tests/together.py
bare_venv; tests/together_fmpy.py runs the FMUs in it), and the C host tests/together_host.c
with nothing but PATH and GREYFMU_PYTHON naming that Python.  What each test checks failed on
96f2739, where every FMU imported its code under public names (PID, _slave, greyfmu, pythonfmu):
the second FMU of ours in a process failed to instantiate without a word, another vendor's FMU
named PID ran our class (or crashed ours), a host's greyfmu replaced the FMU's, four first
instances on four threads crashed a C host, and so on (the figures in each test's docstring).
``GREYFMU_SOAK=1`` repeats the thread trials 30 times and the fmpy leak over 1000 cycles.
"""
from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from pythons import Unavailable, bare_venv
from together import (build_other_release, build_vendor_fmus, compile_host, host_spec, other_greyfmu, results,
                      run_fmpy, run_host)

SOAK = os.environ.get("GREYFMU_SOAK") == "1"
FOUR = ["Step", "PID", "FOPDT", "GrayPredictivePI"]
"""Four different FMUs of ours: a source, the PID, a plant, a grey predictive controller."""
PACKAGE_PREFIX = "_greyfmu_"


@pytest.fixture(scope="module")
def bare_python() -> Path:
    try:
        return bare_venv()
    except Unavailable as why:
        pytest.skip(str(why))


@pytest.fixture(scope="module")
def vendor_fmus(tmp_path_factory) -> dict[str, Path]:
    return build_vendor_fmus(tmp_path_factory.mktemp("vendor"))


@pytest.fixture(scope="module")
def other_release(tmp_path_factory) -> tuple[Path, dict[str, Path]]:
    """Another release of ours: the greyfmu copy whose PID doubles u, and PID and PID3 built from it."""
    folder = other_greyfmu(tmp_path_factory.mktemp("other-greyfmu"))
    return folder, build_other_release(["PID", "PID3"], folder, tmp_path_factory.mktemp("other-release"))


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    return compile_host(tmp_path_factory.mktemp("together-host"))


@pytest.fixture(scope="module")
def fmpy_runs(bare_python, built_fmus, vendor_fmus, other_release):
    """``run(name)``: the fmpy process ``name`` below (run once, shared by the tests), its runs and
    what it left.  An FMU run first in its process computes what it computes alone."""
    from greyfmu.build import build_fmus

    ours, release, theirs = built_fmus, other_release[1], vendor_fmus
    ours3, *fmi3 = build_fmus(["PID3", *(name + "3" for name in FOUR)])
    four3 = dict(zip(FOUR, fmi3))
    orders = {
        "ours": [ours[name] for name in ["GrayPredictivePI", *FOUR, "Step", "PID"]],
        "mixed": [ours["PID"], theirs["PID"], theirs["Step"], release["PID"], ours["Step"], theirs["PID"], ours["PID"],
                  theirs["Step"], release["PID"]],
        "release first": [release["PID"], ours["PID"]],
        "fmi3 mixed": [ours3, theirs["PID3"], release["PID3"], ours3, theirs["PID3"], release["PID3"]],
        "fmi3 ours": [release["PID3"], ours3, release["PID3"]],
        "fmi3 four": [four3[name] for name in [*FOUR, *FOUR]],
        "fmi2 and fmi3": [ours["PID"], ours3, ours["Step"], four3["Step"], ours3, ours["PID"]],
    }
    done: dict[str, tuple[list[dict], dict]] = {}

    def run(name: str) -> tuple[list[dict], dict]:
        if name not in done:
            runs, left = run_fmpy(bare_python, orders[name])
            done[name] = [entry["outputs"] for entry in runs], left
        return done[name]

    return run


# ---- Python hosts (fmpy) ----

def test_our_fmus_one_after_the_other_leave_the_host_as_it_was(fmpy_runs):
    """GrayPredictivePI, Step, PID, FOPDT, GrayPredictivePI, Step, PID through fmpy.simulate_fmu in
    one process (each in a folder fmpy deletes afterwards): all run, a second run as the first;
    sys.path is as before and the only public modules added are the host Python's own (numpy's,
    the standard library's); the FMUs' code is under private names, one package each.  At 96f2739
    the second FMU and every later one failed: ``Failed to instantiate model``, no log line (the
    first FMU's greyfmu, in its deleted folder, served every later import)."""
    outputs, left = fmpy_runs("ours")
    assert outputs[0] == outputs[4] and outputs[1] == outputs[5] == {"y": 1.0}
    assert outputs[2] == outputs[6] == fmpy_runs("mixed")[0][0], "PID computes otherwise than first in its process"
    assert left["path_added"] == [] and left["path_removed"] == [] and left["modules_replaced"] == []
    assert left["public_added"] == [], "an FMU added public modules that are not the host's own"
    packages = {name.split(".")[0] for name in left["private"]}
    assert {package.rsplit("_", 1)[0] for package in packages} == {f"{PACKAGE_PREFIX}{name}" for name in FOUR}


def test_another_vendors_fmus_named_pid_and_step_run_beside_ours_in_any_order(fmpy_runs):
    """Another vendor's plain pythonfmu FMUs also named PID (u = 1.5 (r - y): 2.25 here) and Step
    (y = 7), interleaved with ours in one process: each computes with its own class, ours as
    alone.  At 96f2739, theirs first: SIGSEGV inside our fmi2Instantiate; ours first: theirs
    computed with our class (u = 1.5363)."""
    outputs, _ = fmpy_runs("mixed")
    assert outputs[1] == outputs[5] == {"u": 2.25}
    assert outputs[2] == outputs[7] == {"y": 7.0}
    assert outputs[0] == outputs[6] and outputs[4] == {"y": 1.0}


def test_two_releases_of_ours_each_compute_with_their_own_code(fmpy_runs):
    """PID of this build and of another release (its greyfmu doubles u: another private package),
    interleaved in one process: each gives what it gives first in a process (alone), and they
    differ.  At 96f2739 the second release imported the first one's classes and computed with them."""
    mixed, left = fmpy_runs("mixed")
    release_first, _ = fmpy_runs("release first")
    assert mixed[0] == mixed[6] == release_first[1]
    assert mixed[3] == mixed[8] == release_first[0]
    assert mixed[0]["u"] != mixed[3]["u"]
    assert len({name.split(".")[0] for name in left["private"] if "_PID_" in name}) == 2


@pytest.mark.parametrize("greyfmu", ["another release", "an unrelated package"])
def test_a_host_with_its_own_greyfmu_keeps_it_and_the_fmu_uses_its_own(bare_python, built_fmus, other_release,
                                                                       fmpy_runs, tmp_path, greyfmu):
    """The host imported its own greyfmu first — another release (PID doubled) or an unrelated
    package of that name: the FMU computes as alone and the host's greyfmu stays in sys.modules.
    At 96f2739: another release's code ran in the FMU (u(20 s) = 22.8917 instead of 22.8314 in the
    issue's run); an unrelated package made fmi2Instantiate return NULL, silently."""
    if greyfmu == "another release":
        folder = other_release[0]
    else:
        folder = tmp_path / "unrelated"
        (folder / "greyfmu" / "control").mkdir(parents=True)
        (folder / "greyfmu" / "__init__.py").write_text('"""Not the greyfmu of the FMUs: a name clash."""\n')
        (folder / "greyfmu" / "control" / "__init__.py").write_text("")
        (folder / "greyfmu" / "control" / "pid.py").write_text('WHAT = "the host\'s own module"\n')
    runs, left = run_fmpy(bare_python, [built_fmus["PID"]], "--host-greyfmu", str(folder))
    assert runs[0]["outputs"] == fmpy_runs("mixed")[0][0]
    assert left["host_greyfmu"].startswith(str(folder)) and left["host_greyfmu_kept"]


def test_fmpy_instantiations_grow_the_process_no_more_than_2_kb_each(bare_python, built_fmus, twin_fmus):
    """Instantiate, initialise, one step, free and unload, repeated in fmpy (200 cycles; 1000 with
    GREYFMU_SOAK=1) for PID and for a C FMU (the C twin of Step, tests/twin_fmus.py) in one process:
    PID's growth of resident memory per cycle is within 2 kB of the C FMU's, which is fmpy's own
    (0.8-1.5 kB here).  At 96f2739: 14.7-20.6 kB per cycle for PID (pythonfmu re-ran the whole slave
    module and kept each new class); now 0.7-1.1 kB above the C FMU's (2.0-2.2 kB in all)."""
    cycles = 1000 if SOAK else 200
    runs, _ = run_fmpy(bare_python, [twin_fmus["Step"], built_fmus["PID"]], "--cycles", str(cycles))
    floor, ours = (run["rss_per_cycle"] for run in runs)
    assert ours - floor <= 2048, f"PID grows the process {ours:.0f} B per cycle, a C FMU {floor:.0f} B"


# ---- a C host with a bare environment ----

@pytest.fixture(scope="module")
def deleting_host(host, bare_python, built_fmus, tmp_path_factory):
    """The four FMUs run one after the other in one C host, twice over, each FMU's folder deleted
    once it is unloaded (as fmpy does): the host's run and the folders."""
    root, specs = tmp_path_factory.mktemp("deleted"), []
    for round_ in range(2):
        for name in FOUR:
            specs += host_spec(built_fmus[name], root / f"{round_}-{name}")
    return run_host(host, "delete", 10, specs, bare_python), [root / f"{round_}-{name}" for name in FOUR for round_ in (0, 1)]


def test_a_c_host_that_deletes_each_fmus_folder_runs_them_all(deleting_host):
    """Every run gives its output, the second round the first round's, and the folders are gone.
    At 96f2739 every FMU after the first: fmi2Instantiate returned NULL, no log line."""
    done, folders = deleting_host
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    found = results(done)
    outputs = [found[index, "output"] for index in range(8)]
    assert outputs[:4] == outputs[4:]
    assert not any(folder.exists() for folder in folders)


def test_first_instances_of_four_fmus_on_four_threads_start_python_once(host, bare_python, built_fmus, deleting_host,
                                                                      tmp_path):
    """Four threads make the first instances of four different FMUs at the same moment (a barrier),
    in a fresh host each trial (3 trials; 30 with GREYFMU_SOAK=1): every trial ends normally with
    the outputs of the same FMUs run one after the other.  At 96f2739: 8 of 10 trials crashed
    (Fatal Python error: init_fs_encoding, SIGSEGV) or refused with a wrongful "cannot import
    numpy": the lock of Python's start was per FMU binary, the start per process."""
    expected = {key: value for key, value in results(deleting_host[0]).items() if key[1] == "output" and key[0] < 4}
    assert len(expected) == 4, deleting_host[0].stdout[-2000:]
    specs = []
    for name in FOUR:
        specs += host_spec(built_fmus[name], tmp_path / name)
    for trial in range(30 if SOAK else 3):
        done = run_host(host, "threads", 10, specs, bare_python)
        assert done.returncode == 0, f"trial {trial}: exit {done.returncode}\n{done.stdout[-2000:]}{done.stderr[-3000:]}"
        assert results(done) == expected, f"trial {trial}"


def _lines_of(done, case: str) -> list[str]:
    """The log lines the host printed for ``case`` (between its "case" line and the next)."""
    lines, inside = [], False
    for line in done.stdout.splitlines():
        if line.startswith("case "):
            inside = line == f"case {case}"
        elif inside and line.startswith("log "):
            lines.append(line)
    return lines


def test_foreign_or_damaged_state_bytes_are_refused_with_one_line_and_the_instance_lives(host, bare_python,
                                                                                       built_fmus, tmp_path):
    """loggingOn = false.  fmi2DeSerializeFMUstate of Step's state, of PID's own state cut in half,
    of its 20-byte header alone, of 256 random bytes and of no bytes: fmi2Error with one line saying
    what is wrong; then PID's own state is restored and the instance steps on.  At 96f2739: the
    first answer was fmi2Fatal with no line (the instance lost, §2.1.3 misused)."""
    specs = host_spec(built_fmus["PID"], tmp_path / "PID") + host_spec(built_fmus["Step"], tmp_path / "Step")
    done = run_host(host, "bad-states", 0, specs, bare_python)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    found = results(done)
    why = {"foreign": "they hold a state of 'Step'", "truncated": "truncated", "header": "Ran out of input",
           "random": "they do not start with", "empty": "the 0 bytes given"}
    for case, text in why.items():
        assert found[0, f"deserialize-{case}"] == "3", case
        lines = _lines_of(done, case)
        assert len(lines) == 1 and " 3 " in lines[0] and text in lines[0], (case, lines)
    assert found[0, "deserialize-own"] == found[0, "set-own"] == found[0, "step-after"] == "0"


def test_an_exception_in_the_fmus_code_is_fmi2error_with_one_line_and_reset_recovers(host, bare_python, built_fmus,
                                                                                     tmp_path):
    """loggingOn = false.  integral_mode = 5 (no item) refused at fmi2ExitInitializationMode: a
    ValueError in the slave, answered fmi2Error with one line naming the parameter; fmi2Reset then
    brings the instance back.  At 96f2739: fmi2Fatal, no line, the instance lost."""
    from fmpy import read_model_description

    mode = next(v.valueReference for v in read_model_description(str(built_fmus["PID"])).modelVariables
                if v.name == "integral_mode")
    specs = host_spec(built_fmus["PID"], tmp_path / "PID")
    specs[-1] = str(mode)
    done = run_host(host, "bad-parameter", 5, specs, bare_python)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    found = results(done)
    assert (found[0, "set"], found[0, "exit"], found[0, "reset"], found[0, "again"]) == ("0", "3", "0", "0")
    logs = [line for line in done.stdout.splitlines() if line.startswith("log ")]
    assert len(logs) == 1 and "fmi2ExitInitializationMode: ValueError: invalid parameters: integral_mode = 5" in logs[0]


def test_an_fmu_that_cannot_import_its_slave_says_why_it_returns_null(host, bare_python, built_fmus, tmp_path):
    """loggingOn = false.  PID's slave module deleted from its folder: fmi2Instantiate returns NULL
    after one line naming the failed import.  At 96f2739: NULL and nothing else."""
    specs = host_spec(built_fmus["PID"], tmp_path / "PID")
    module = (tmp_path / "PID" / "resources" / "slavemodule.txt").read_text().strip()
    package, model = module.split(".")
    (tmp_path / "PID" / "resources" / package / f"{model}.py").unlink()
    done = run_host(host, "sequence", 1, specs, bare_python)
    assert done.returncode == 1 and results(done) == {(0, "instantiate"): "null"}
    logs = [line for line in done.stdout.splitlines() if line.startswith("log ")]
    assert len(logs) == 1 and module in logs[0] and "ModuleNotFoundError" in logs[0], logs


def test_a_c_host_grows_no_more_than_2_kb_per_instance_or_per_state(host, bare_python, built_fmus, tmp_path):
    """1000 instantiate/initialise/step/free cycles of PID: at most 2 kB of resident memory per
    cycle (96f2739: 19.2 kB; now 1.5 kB).  200 steps of OSMMGPC (1000 with GREYFMU_SOAK=1), each
    followed by fmi2GetFMUstate with the previous state passed back, as Simulink's operating points
    do (FMI 2.0 §2.1.8 allows it): at most 2 kB per step (96f2739: 50.9 kB, a whole state leaked
    per call, 49.9 MB over 1000 steps; now 0.2 kB)."""
    cycled = run_host(host, "cycles", 1000, host_spec(built_fmus["PID"], tmp_path / "PID"), bare_python)
    assert cycled.returncode == 0, cycled.stdout[-2000:] + cycled.stderr[-2000:]
    growth = int(next(line for line in cycled.stdout.splitlines() if line.startswith("rss-growth")).split()[1])
    assert growth <= 1000 * 2048, f"{growth / 1000:.0f} B per instantiate/free cycle"
    steps = 1000 if SOAK else 220  # the first 20 are not counted
    stated = run_host(host, "states", steps, host_spec(built_fmus["OSMMGPC"], tmp_path / "OSMMGPC"), bare_python)
    assert stated.returncode == 0, stated.stdout[-2000:] + stated.stderr[-2000:]
    growth = int(next(line for line in stated.stdout.splitlines() if line.startswith("rss-growth")).split()[1])
    assert growth <= (steps - 20) * 2048, f"{growth / (steps - 20):.0f} B per step with fmi2GetFMUstate"


@pytest.mark.parametrize("mode", ["sigint-main", "sigint-thread"])
def test_ctrl_c_ends_a_c_host_without_a_handler(host, bare_python, built_fmus, tmp_path, mode):
    """After the FMU ran (instantiated on the main thread, or on a thread that has ended since),
    SIGINT's disposition is still the default and SIGINT ends the host.  At 96f2739 Python's
    handler was installed (the numerics import signal), and the host lived on: Ctrl-C lost."""
    done = run_host(host, mode, 5, host_spec(built_fmus["PID"], tmp_path / "PID"), bare_python)
    assert "sigint-disposition default" in done.stdout, done.stdout[-2000:] + done.stderr[-2000:]
    assert done.returncode == -signal.SIGINT and "survived" not in done.stdout


def test_a_c_hosts_own_sigint_handler_stays(host, bare_python, built_fmus, tmp_path):
    done = run_host(host, "sigint-handler", 5, host_spec(built_fmus["PID"], tmp_path / "PID"), bare_python)
    assert done.returncode == 3, done.stdout[-2000:] + done.stderr[-2000:]
    assert "sigint-disposition host" in done.stdout and "host-handler-calls 1" in done.stdout


# ---- FMI 3.0 ----

def test_fmi3_fmus_of_ours_of_two_releases_and_another_vendors_pid3_in_one_process(fmpy_runs):
    """Another vendor's plain pythonfmu3 PID3 (u = 2.25), ours and another release of ours (u
    doubled), interleaved in one fmpy process: each computes with its own code, ours as alone;
    ours leave sys.path and the public modules as they were.  At 96f2739 (pythonfmu3 embedded
    under its public name): theirs first made ours fail (fmi3Fatal in fmi3SetFloat64, running
    their class)."""
    mixed, _ = fmpy_runs("fmi3 mixed")
    ours, left = fmpy_runs("fmi3 ours")
    assert mixed[1] == mixed[4] == {"u": 2.25}
    assert mixed[0] == mixed[3] == ours[1]
    assert mixed[2] == mixed[5] == ours[0] == ours[2] != ours[1]
    assert left["path_added"] == [] and left["public_added"] == []


def test_four_fmi3_fmus_of_ours_in_one_process_compute_as_their_fmi2_siblings(fmpy_runs):
    """Step3, PID3, FOPDT3, GrayPredictivePI3 twice over in one fmpy process (each its own private
    package): every run gives what the FMI 2.0 sibling gives (first in its process), the second
    round the first's; sys.path and the public modules are as before.  Before issue 41 only PID3
    existed as FMI 3.0."""
    fmi3, left = fmpy_runs("fmi3 four")
    fmi2, _ = fmpy_runs("ours")
    assert fmi3[:4] == fmi3[4:] == fmi2[1:5]
    assert left["path_added"] == [] and left["public_added"] == []
    packages = {name.split(".")[0].rsplit("_", 1)[0] for name in left["private"]}
    assert packages == {f"{PACKAGE_PREFIX}{name}" for name in FOUR}


def test_the_fmi2_and_fmi3_builds_of_one_model_in_one_process_compute_the_same(fmpy_runs):
    """PID, PID3, Step, Step3, PID3, PID in one fmpy process: each FMI 3.0 FMU gives what its FMI
    2.0 sibling gives, in any order."""
    outputs, left = fmpy_runs("fmi2 and fmi3")
    assert outputs[0] == outputs[1] == outputs[4] == outputs[5] == fmpy_runs("mixed")[0][0]
    assert outputs[2] == outputs[3] == {"y": 1.0}
    assert left["path_added"] == [] and left["public_added"] == []


def test_a_process_that_ran_our_fmi3_fmu_builds_fmi3_fmus_with_binaries(tmp_path):
    """fmpy.simulate_fmu(PID3.fmu), then greyfmu build PID3 in the same process: the FMU ran with
    its own private copy of pythonfmu3, so the build uses the installed pythonfmu3 and ships its
    binaries.  At 96f2739 the FMU's resources/pythonfmu3 shadowed the installed one and the build
    refused (BuildError: no binaries)."""
    import subprocess
    import sys

    from greyfmu.build import build_fmus

    (fmu,) = build_fmus(["PID3"])
    script = (f"import fmpy, zipfile; fmpy.simulate_fmu({str(fmu)!r}, stop_time=0.2)\n"
              "from greyfmu.build import build_fmus\n"
              f"(built,) = build_fmus(['PID3'], out_dir={str(tmp_path)!r}, force=True)\n"
              "print(sorted(n for n in zipfile.ZipFile(built).namelist() if n.startswith('binaries/')))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "binaries/x86_64-linux/PID3.so" in done.stdout
