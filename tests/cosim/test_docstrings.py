"""Every role and every stage of a run says what it does (issue 29: 7 of the 8 public methods of
`Execution` had no docstring): each public method of the master's Protocols (cosim/: a class
deriving from ``Protocol``), of `Execution` and of `Stepping` has a docstring; an implementation
of a Protocol method may lean on the Protocol's."""
from __future__ import annotations

import ast
from pathlib import Path

COSIM = Path(__file__).resolve().parents[2] / "cosim"
STAGES = {"Execution", "Stepping"}


def _documented_classes() -> list[tuple[Path, ast.ClassDef]]:
    found = []
    for path in sorted(COSIM.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and (node.name in STAGES or any(
                    getattr(base, "id", getattr(base, "attr", None)) == "Protocol" for base in node.bases)):
                found.append((path, node))
    return found


def test_every_public_method_of_the_protocols_and_the_run_stages_has_a_docstring():
    classes = _documented_classes()
    assert STAGES <= {c.name for _, c in classes} and len(classes) >= 7, [c.name for _, c in classes]
    undocumented = [f"{path.relative_to(COSIM.parent)}:{f.lineno} {c.name}.{f.name}" for path, c in classes
                    for f in c.body if isinstance(f, ast.FunctionDef) and not f.name.startswith("_")
                    and ast.get_docstring(f) is None]
    assert undocumented == []
