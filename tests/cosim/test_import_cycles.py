"""No import cycle in the cosim package (issue 16): each module imports only what comes
before it on the data path, so any module can be read, tested and replaced on its own.

Read with the standard library's `ast`, without importing anything: every ``import`` and
``from ... import`` of a cosim module, at module level and inside functions, including
those under ``if TYPE_CHECKING:`` (none is excluded: a cycle that exists only for the type
checker still ties the two modules together).  Importing a submodule is an edge to it and to
its packages (Python runs a package's ``__init__`` before any of its submodules), but not to the
importer's own packages (Python has run those already: a package importing its own submodules
is how a package is built, not a cycle).

The stages (issue 40) import one way: `cosim.model` (the records), then `cosim.read`,
`cosim.plan`, `cosim.record`, `cosim.run`, `cosim.present`, then what uses them all (`cosim.cli`,
`cosim.pytest_plugin`, `cosim.sweep`); `cosim.errors`, `cosim.safeio`, `cosim.extras` and
`cosim.kernel` (the compiled library of run and record) come before all.
"""
from __future__ import annotations

import ast
from pathlib import Path

import cosim
from cosim.plan.graph import tarjan

PACKAGE = Path(cosim.__file__).parent


def modules(root: Path = PACKAGE) -> dict[str, Path]:
    """Every module of the package by dotted name (``cosim.run.instances.fmi2``; a package is its
    ``__init__``)."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The package's modules that module ``name`` imports anywhere in its file."""
    is_package = path.name == "__init__.py"
    targets: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - node.level + 1]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module
            targets.add(origin)
            targets.update(f"{origin}.{alias.name}" for alias in node.names)  # a submodule imported by name
    packages = {".".join(t.split(".")[:i]) for t in targets for i in range(1, t.count(".") + 1)}
    return {t for t in targets | packages if t in known and t != name and not name.startswith(t + ".")}


def import_graph() -> dict[str, set[str]]:
    found = modules()
    return {name: imports(name, path, set(found)) for name, path in found.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    return [scc for scc in tarjan(sorted(graph), {k: sorted(v) for k, v in graph.items()}) if len(scc) > 1]


def test_no_import_cycle_in_cosim():
    graph = import_graph()
    assert len(graph) > 20 and "cosim.run.instances.fmi2" in graph and "cosim.sweep.values" in graph
    assert cycles(graph) == []


def test_the_data_model_and_the_readers_import_no_later_stage():
    """structure.py imports no reader or check; ssp.py and flatten.py nothing of the plan or the run."""
    graph = import_graph()

    def reach(start: str) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            for nxt in graph[todo.pop()] - seen:
                seen.add(nxt)
                todo.append(nxt)
        return seen

    later = {"cosim.plan.build", "cosim.plan.parameters", "cosim.plan.routing", "cosim.run.execution", "cosim.run.simulation",
             "cosim.run.instances", "cosim.sweep", "cosim.cli"}
    assert reach("cosim.model.structure") <= {f"cosim.model.{m}" for m in ("units", "fmu", "frozen", "transforms")} \
        | {"cosim.errors"}
    assert not (reach("cosim.read.ssp") | reach("cosim.read.flatten")) & later
    assert not reach("cosim.plan.graph") & later


#: the order of the stages: a module imports modules of its own rank or lower
RANKS = {"errors": 0, "safeio": 0, "extras": 0, "kernel": 0, "model": 1, "read": 2, "plan": 3, "record": 4,
         "run": 5, "present": 6, "cli": 7, "pytest_plugin": 7, "sweep": 7, "scaffold": 7,
         "regression": 7, "tune": 7}


def _rank(module: str) -> int:
    parts = module.split(".")
    return RANKS[parts[1]] if len(parts) > 1 else max(RANKS.values()) + 1


def test_the_stages_import_one_way():
    """No stage imports a later one (issue 40: `single`, a preparation module, imported the run's
    `simulation` and, inside a function, `sweep.values`, while `sweep` imported `single`; the run's
    `simulation` imported `plots` for the units of a sweep)."""
    graph = import_graph()
    assert set(RANKS) >= {m.split(".")[1] for m in graph if m.count(".") >= 1}, "a module outside the stages"
    backward = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets if _rank(t) > _rank(m))
    assert backward == []


def test_the_checker_finds_a_cycle(tmp_path):
    """The check itself: two modules importing each other (one inside a function, one under
    TYPE_CHECKING, one relative and one absolute) are reported."""
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .sub import b\n")
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "b.py").write_text("def f():\n    import pkg.a\n")
    (package / "c.py").write_text("from . import a\n")
    found = modules(package)
    graph = {name: imports(name, path, set(found)) for name, path in found.items()}
    assert graph["pkg.a"] == {"pkg.sub", "pkg.sub.b"} and graph["pkg.sub.b"] == {"pkg.a"}

    assert graph["pkg.c"] == {"pkg.a"}
    assert cycles(graph) == [["pkg.a", "pkg.sub.b"]] or cycles(graph) == [["pkg.sub.b", "pkg.a"]]
    # a module importing a submodule of a package whose __init__ imports it back (issue 40: single ->
    # sweep.values inside a function, while sweep/__init__ imported single): the package is an edge
    (package / "sub2").mkdir()
    (package / "sub2" / "__init__.py").write_text("from ..d import f\n")
    (package / "sub2" / "c.py").write_text("X = 1\n")
    (package / "d.py").write_text("def f():\n    from .sub2.c import X\n")
    found = modules(package)
    graph = {name: imports(name, path, set(found)) for name, path in found.items()}
    assert graph["pkg.d"] == {"pkg.sub2", "pkg.sub2.c"} and ["pkg.d", "pkg.sub2"] in [sorted(c) for c in cycles(graph)]
