"""The native systems of benchmarks/bench_native.py: FMUs, SSP folders and container descriptions.

Two families of FMI 2.0 Co-Simulation FMUs, none of them Python:

* ``c``: two minimal C FMUs compiled here (gcc, with tests/cfmus.py):
  ``VanDerPol`` (outputs x1, x2: x1' = x2, x2' = mu (1 - x1²) x2 - x1, mu = 1, x(0) = (2, 0),
  one classical Runge-Kutta step per fmi2DoStep) and ``Lag`` (direct feedthrough:
  y = k u + (1 - k) x with a first-order lag x' = u - x by one explicit Euler step, k = 0.5);
* ``om``: OpenModelica exports shipped by gemseo-fmu 3.1.1 (/work/shared/thirdparty.md):
  ``Mass_Damper`` (output y, its input f left at 0) and ``add`` (y = k1 u1 + k2 u2, direct
  feedthrough, u2 left at 0).

Systems of N FMUs: ``independent`` (N copies of the first FMU, nothing connected) and
``chained`` (the first FMU, then N - 1 feedthrough blocks in series: head.y -> b2.u -> b3.u ...).
Every connector carries an ``ssc:Real`` type element (libcosim needs one).
"""
from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from cfmus import build_c_fmu, fmi2_description  # tests/ is on sys.path (benchmarks/bench_native.py puts it there)
from peers import gemseo_fmu_dir
from ssdgen import ssd_text, write_system

__all__ = ["FAMILIES", "Family", "System", "build_container", "build_family", "native_system", "write_native_system"]


@dataclass(frozen=True)
class Family:
    """A source FMU with its outputs and a feedthrough block with its input and output."""

    name: str
    head: str              # FMU file stem
    head_outputs: tuple[str, ...]
    block: str
    block_input: str
    block_output: str
    head_chain_output: str  # the head's output that feeds the chain


FAMILIES = {
    "c": Family("C (VanDerPol, Lag)", "VanDerPol", ("x1", "x2"), "Lag", "u", "y", "x1"),
    "om": Family("OpenModelica (Mass_Damper, add)", "Mass_Damper", ("y",), "add", "u1", "y", "y"),
}


def _model_description(name: str, variables: list[tuple[str, int, str, float | None]], dependencies: dict) -> str:
    guid = "{b3c1%04x-0000-4000-8000-%012x}" % (len(name), sum(map(ord, name)))
    return fmi2_description(name, variables, dependencies, guid)


VAN_DER_POL = r"""
static void start(S *s) { s->r[0] = 2.0; s->r[1] = 0.0; s->r[2] = 1.0; }
static void calculate(S *s) {}
static void rhs(double mu, double x1, double x2, double *d1, double *d2) {
    *d1 = x2; *d2 = mu * (1.0 - x1 * x1) * x2 - x1; }
static int step(S *s, double t, double h) {   /* one classical Runge-Kutta step */
    double x1 = s->r[0], x2 = s->r[1], mu = s->r[2], a1, a2, b1, b2, c1, c2, d1, d2;
    rhs(mu, x1, x2, &a1, &a2);
    rhs(mu, x1 + 0.5 * h * a1, x2 + 0.5 * h * a2, &b1, &b2);
    rhs(mu, x1 + 0.5 * h * b1, x2 + 0.5 * h * b2, &c1, &c2);
    rhs(mu, x1 + h * c1, x2 + h * c2, &d1, &d2);
    s->r[0] = x1 + h / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1);
    s->r[1] = x2 + h / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2);
    return 0; }
"""

LAG = r"""
static void start(S *s) { s->r[3] = 0.5; }
static void calculate(S *s) { s->r[1] = s->r[3] * s->r[0] + (1.0 - s->r[3]) * s->r[2]; }
static int step(S *s, double t, double h) { s->r[2] += h * (s->r[0] - s->r[2]); return 0; }
"""


def build_family(family: str, folder: Path) -> dict[str, Path]:
    """The two FMUs of ``family`` ("c": compiled into ``folder``; "om": gemseo-fmu's files)."""
    if family == "c":
        return {
            "VanDerPol": build_c_fmu(folder, "VanDerPol", _model_description(
                "VanDerPol", [("x1", 0, "output", None), ("x2", 1, "output", None), ("mu", 2, "parameter", 1.0)], {}),
                VAN_DER_POL),
            "Lag": build_c_fmu(folder, "Lag", _model_description(
                "Lag", [("u", 0, "input", 0.0), ("y", 1, "output", None), ("k", 3, "parameter", 0.5)], {"y": ["u"]}),
                LAG),
        }
    if family == "om":
        return {stem: gemseo_fmu_dir() / f"{stem}.fmu" for stem in ("Mass_Damper", "add")}
    raise ValueError(f"unknown FMU family {family!r}: {sorted(FAMILIES)}")


@dataclass(frozen=True)
class System:
    """A system of ``n`` FMUs: its components (name -> (FMU stem, outputs)) and connections."""

    family: Family
    topology: str          # "independent" or "chained"
    n: int
    components: dict[str, tuple[str, tuple[str, ...]]]
    connections: list[tuple[str, str, str, str]]

    @property
    def label(self) -> str:
        return f"{self.topology} {self.n}"


def native_system(family: Family, topology: str, n: int) -> System:
    """``n`` FMUs of ``family``, ``independent`` or ``chained`` (module docstring)."""
    if topology == "independent":
        return System(family, topology, n, {f"m{i}": (family.head, family.head_outputs) for i in range(1, n + 1)}, [])
    if topology != "chained":
        raise ValueError(f"topology must be 'independent' or 'chained', not {topology!r}")
    if n < 2:
        raise ValueError("a chain needs at least 2 FMUs")
    components = {"m1": (family.head, family.head_outputs)}
    connections = []
    upstream, out = "m1", family.head_chain_output
    for i in range(2, n + 1):
        components[f"b{i}"] = (family.block, (family.block_output,))
        connections.append((upstream, out, f"b{i}", family.block_input))
        upstream, out = f"b{i}", family.block_output
    return System(family, topology, n, components, connections)


def write_native_system(system: System, fmus: dict[str, Path], folder: Path, stop: float, step: float) -> Path:
    """``system`` as an SSP folder (SystemStructure.ssd and resources/) in ``folder``."""
    inputs = {dst: dv for _, _, dst, dv in system.connections}
    components = {name: (f"{stem}.fmu", {**{o: "output" for o in outputs},
                                          **({inputs[name]: "input"} if name in inputs else {})})
                  for name, (stem, outputs) in system.components.items()}
    text = ssd_text(f"{system.topology}_{system.n}", components, system.connections, stop=stop, step=step)
    text = text.replace('kind="input"/>', 'kind="input"><ssc:Real/></ssd:Connector>') \
               .replace('kind="output"/>', 'kind="output"><ssc:Real/></ssd:Connector>')
    used = {stem for stem, _ in system.components.values()}
    return write_system(folder, {f"{stem}.fmu": fmus[stem] for stem in used}, text)


def build_container(system: System, fmus: dict[str, Path], folder: Path, step: float) -> Path:
    """``system`` as a fmu-manipulation-toolbox 2.0 container FMU (``fmucontainer``, one thread,
    its default parallel schedule) in ``folder``; every output of every embedded FMU is an
    output of the container, named ``component_output``."""
    folder.mkdir(parents=True, exist_ok=True)
    names = {}
    for name, (stem, _) in system.components.items():
        names[name] = f"{name}.fmu"
        (folder / names[name]).write_bytes(fmus[stem].read_bytes())
    description = {
        "name": "container.fmu", "step_size": step, "mt": False,
        "auto_link": False, "auto_input": False, "auto_output": False,
        "fmu": list(names.values()),
        "link": [[names[a], ca, names[b], cb] for a, ca, b, cb in system.connections],
        "output": [[names[c], o, f"{c}_{o}"] for c, (_, outputs) in system.components.items() for o in outputs],
    }
    (folder / "container.json").write_text(json.dumps(description, indent=1))
    tool = Path(sys.executable).parent / "fmucontainer"
    completed = subprocess.run([str(tool), "-container", "container.json", "-fmu-directory", str(folder)],
                               cwd=folder, capture_output=True, text=True)
    container = folder / "container.fmu"
    if completed.returncode != 0 or not container.exists():
        raise RuntimeError(f"fmucontainer failed on {folder / 'container.json'}:\n{completed.stdout}{completed.stderr}")
    return container
