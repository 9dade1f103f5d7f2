"""The layout of the project as the tests rely on it: what may import fmpy, what the data model
imports, that docs/architecture.md names every module, and that without pythonfmu the master names
the provider it cannot load.  That `tests/cosim/` runs without pythonfmu is checked around each of
its tests (tests/cosim/conftest.py, tests/blocker.py; issue 29 ran all of tests/cosim a second time
in a child pytest for it, issue 40 checks it in the run itself)."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

from blocker import environment

ROOT = Path(__file__).resolve().parents[1]


def test_a_provider_that_cannot_be_imported_is_named_not_raised(tmp_path, twin_fmus):
    """Without pythonfmu, greyfmu's FMU provider (the entry point greyfmu.build:provide_fmu)
    cannot be imported: an FMU not beside the SSD was a raw ImportError traceback, even when
    --fmu-dir holds it.  Now the run finds it in --fmu-dir, and an FMU found nowhere is the usual
    "not found" naming the provider and why it is not loaded (exit 2)."""
    from ssdgen import ssd_text, write_system

    folder = write_system(tmp_path / "sys", {}, ssd_text("t", {"g": ("Gain.fmu", {"u": "input", "y": "output"})}, []))
    env = environment(tmp_path / "blocker")
    missing = subprocess.run([sys.executable, "-m", "cosim.cli", "validate", str(folder)], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2 and "Traceback" not in missing.stderr, missing.stderr
    assert "was not found" in missing.stderr
    assert "greyfmu.build:provide_fmu (not loaded: greyfmu.build is blocked" in missing.stderr, missing.stderr
    found = subprocess.run([sys.executable, "-m", "cosim.cli", "validate", str(folder), "--fmu-dir",
                            str(twin_fmus["Gain"].parent)], cwd=ROOT, env=env, capture_output=True, text=True,
                           timeout=120)
    assert found.returncode == 0, found.stderr


#: the master's modules that may import fmpy (issue 29: 13 did at 520086d, the plan, routing, parameters,
#: inputs and structure among them): the description reader and the instances, which wrap fmpy's
#: model description and FMI calls, and three that use a fact of fmpy's (loadable: its platform
#: folder names; single: its automatic output interval, as `fmpy simulate` picks it; ssp: the SSP
#: XSDs it ships); every other module reads our own records (cosim.read.description)
FMPY_USERS = {"cosim/read/description.py", "cosim/run/instances/fmi2.py", "cosim/run/instances/fmi3.py", "cosim/run/instances/me.py",
              "cosim/run/instances/loading.py",
              "cosim/read/loadable.py", "cosim/read/single.py", "cosim/read/ssp.py"}


def test_only_the_description_reader_and_the_instances_import_fmpy():
    importing = set()
    for path in sorted((ROOT / "cosim").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            if any(n == "fmpy" or n.startswith("fmpy.") for n in names):
                importing.add(path.relative_to(ROOT).as_posix())
    assert importing <= FMPY_USERS, sorted(importing - FMPY_USERS)


def test_the_data_model_imports_no_fmpy():
    """The records every stage shares (`cosim.model`: the structure, the Plan, the FMU description
    records, units, transformations) are plain data: importing them loads no fmpy (issue 40: the
    records lived in the module that read them with fmpy)."""
    code = ("import sys, cosim.model.structure, cosim.model.fmu, cosim.model.units, cosim.model.grid; "
            "print(sorted(m for m in sys.modules if m == 'fmpy' or m.startswith('fmpy.')))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr


def test_docs_architecture_has_a_row_for_every_module_and_no_other():
    """docs/architecture.md's module map (issue 40: wrong in 12 places, 8 modules with no row) names
    every module of cosim/ once, and no module that does not exist; a package whose __init__.py
    holds only its docstring needs no row."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    table = text.split("## Module map", 1)[1].split("\n## ", 1)[0].split("\n### ", 1)[0]
    rows = re.findall(r"^\| `(cosim/[^`]+\.py)` \|", table, flags=re.M)
    modules = set()
    for path in (ROOT / "cosim").rglob("*.py"):
        tree = ast.parse(path.read_text())
        body = tree.body[1:] if tree.body and isinstance(tree.body[0], ast.Expr) else tree.body
        if path.name != "__init__.py" or body:
            modules.add(path.relative_to(ROOT).as_posix())
    assert len(rows) == len(set(rows)), sorted(r for r in rows if rows.count(r) > 1)
    assert sorted(modules - set(rows)) == [] and sorted(set(rows) - modules) == []
