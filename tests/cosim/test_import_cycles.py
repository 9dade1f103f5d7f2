"""No import cycle in the cosim package (issue 16): each module imports only what comes
before it on the data path, so any module can be read, tested and replaced on its own.

Read with the standard library's `ast`, without importing anything: every ``import`` and
``from ... import`` of a cosim module, at module level and inside functions, including
those under ``if TYPE_CHECKING:`` (none is excluded: a cycle that exists only for the type
checker still ties the two modules together).  Importing a submodule is an edge to it and to
its package, but not to the importer's own packages (Python has run those already: a
package importing its own submodules is how a package is built, not a cycle).
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
    return {t for t in targets if t in known and t != name and not name.startswith(t + ".")}


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
