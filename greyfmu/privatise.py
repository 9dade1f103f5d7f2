"""Put the Python code an FMU embeds under a name private to that FMU (build side; not embedded).

pythonfmu and pythonfmu3 import an FMU's slave module by the name in ``resources/slavemodule.txt``
(pythonfmu 0.7.0's ``findClass``, pythonfmu3 0.3.4's ``PySlaveInstance``) after inserting the
FMU's ``resources/`` at the front of ``sys.path``, so everything the FMU embeds — its slave
module, ``_slave``, the greyfmu package, pythonfmu's own run-time — would be imported under
public top-level names, once per process: a second FMU of ours found the first one's greyfmu
in ``sys.modules`` (in a folder fmpy had deleted), another vendor's FMU named ``PID`` ran our
class (or we theirs, or the host crashed), two releases of ours shared one copy's code, and a
host's own ``greyfmu`` replaced the FMU's.

`privatise` moves every Python module of ``resources/`` into one package,
``resources/_greyfmu_<model>_<hash>/`` (the hash: SHA-256 of the embedded sources and the
requirements, 12 hex digits), rewrites each absolute import of one of them to name that package,
and points ``slavemodule.txt`` at ``<package>.<model>``.  Its file ``resources/<package>.<model>.py``
(pythonfmu reads the slave's source there) is a stub: pythonfmu 0.7.0 executes it in the slave
module's namespace at every instantiation and keeps each class it defines alive (it never
releases the list it makes of each class's ``__mro__``, nor the reprs it makes of them: 20 kB per
instantiation when that was the whole slave module), so the stub binds the class's name to a
two-class stand-in made once (`stub`); pythonfmu3 only searches it for the class statement.  Imports of
modules the FMU does not embed (numpy, scipy, the standard library) are left as they are: the
FMU uses the host's.

The run-time package (`Runtime`) keeps only the modules a slave runs with: without its builder
it cannot be mistaken for the installed pythonfmu by a build in the same process.
"""

from __future__ import annotations

import ast
import hashlib
import io
import re
import tokenize
from dataclasses import dataclass

PACKAGE_PREFIX = "_greyfmu_"
"""Every FMU's private package is named ``_greyfmu_<model>_<hash>``."""
HASH_DIGITS = 12


class PrivatiseError(ValueError):
    """The FMU's Python code cannot be moved under a private name (an import this module cannot rewrite)."""


@dataclass(frozen=True)
class Runtime:
    """A pythonfmu run-time package an FMU embeds: its name and the modules a slave runs with."""

    name: str
    modules: tuple[str, ...]
    base_class: str
    """The slave base class pythonfmu3 looks for in the stub's class statement."""
    builder_import: str = "from .builder import FmuBuilder\n"
    """The line of the package's ``__init__.py`` that is left out (the builder is not shipped)."""


PYTHONFMU = Runtime("pythonfmu", ("__init__.py", "_version.py", "default_experiment.py", "enums.py", "fmi2slave.py",
                                  "logmsg.py", "variables.py"), "Fmi2Slave")
"""pythonfmu 0.7.0; builder, csvbuilder, deploy, __main__ and osutil build or deploy FMUs."""
PYTHONFMU3 = Runtime("pythonfmu3", ("__init__.py", "_version.py", "cosimulation.py", "default_experiment.py", "enums.py",
                                    "fmi3slave.py", "logmsg.py", "modelexchange.py", "unit.py", "variable_types.py",
                                    "variables.py"), "Fmi3Slave")
"""pythonfmu3 0.3.4; builder, deploy, __main__ and osutil build or deploy FMUs."""


def private_package(model: str, sources: dict[str, bytes], requirements: tuple[str, ...]) -> str:
    """``_greyfmu_<model>_<hash>``: the hash covers every embedded source (name and bytes) and the
    requirements, so two builds whose code differs get two packages and one build one name."""
    digest = hashlib.sha256()
    for name in sorted(sources):
        digest.update(name.encode() + b"\0" + hashlib.sha256(sources[name]).digest())
    digest.update("\n".join(requirements).encode())
    return f"{PACKAGE_PREFIX}{model}_{digest.hexdigest()[:HASH_DIGITS]}"


def privatise(entries: dict[str, bytes], model: str, runtime: Runtime, requirements: tuple[str, ...]) -> dict[str, bytes]:
    """``entries`` (the archive pythonfmu's builder wrote) with every Python module of
    ``resources/`` moved into the FMU's private package (see the module docstring).  PrivatiseError
    when the run-time package is not the expected one or an import cannot be rewritten."""
    if not model.isidentifier():
        raise PrivatiseError(f"{model}: the model name is not a Python identifier")
    sources = _runtime_only(entries, model, runtime)
    sources.update({name: data for name, data in entries.items()
                    if name.startswith("resources/") and name.endswith(".py")
                    and not name.startswith(f"resources/{runtime.name}/") and "__pycache__" not in name})
    if f"resources/{model}.py" not in sources:
        raise PrivatiseError(f"{model}: the FMU has no resources/{model}.py (the slave module is named after its class)")
    package = private_package(model, sources, requirements)
    embedded = frozenset(name.removeprefix("resources/").split("/")[0].removesuffix(".py") for name in sources)
    result = {name: data for name, data in entries.items()
              if not (name in sources or name.startswith(f"resources/{runtime.name}/") or "__pycache__" in name)}
    for name, data in sources.items():
        moved = f"resources/{package}/{name.removeprefix('resources/')}"
        result[moved] = privatised_imports(data.decode("utf-8"), embedded, package, moved).encode("utf-8")
    result.setdefault(f"resources/{package}/__init__.py",
                      f'"""The Python code of the greyfmu FMU {model}, under a name private to this build."""\n'.encode())
    result["resources/slavemodule.txt"] = f"{package}.{model}".encode()
    result[f"resources/{package}.{model}.py"] = stub(model, runtime).encode()
    for name, data in result.items():
        if name.startswith(f"resources/{package}/") and name.endswith(".py"):
            _check_no_public_import(data.decode("utf-8"), embedded, name)
    return result


def stub(model: str, runtime: Runtime) -> str:
    """The file pythonfmu reads as the slave module's source (``<package>.<model>.py``): for
    pythonfmu 0.7.0, code run in the slave module's namespace at each instantiation, which names
    the class and defines none; for pythonfmu3, the class statement it searches (never run)."""
    if runtime is PYTHONFMU3:
        return (f"# pythonfmu3 reads the name of the slave class of this FMU here; the class is the module's.\n"
                f"class {model}({runtime.base_class}):\n    pass\n")
    return (f"# pythonfmu 0.7.0 runs this in the slave module's namespace at each instantiation and takes the\n"
            f"# module's attribute named like the class it defines that derives from one named Fmi2Slave: {model}.\n"
            f"# It never releases the list it makes of that class's __mro__, so the class is a stand-in made once.\n"
            f"try:\n"
            f"    {model} = _pythonfmu_stand_in\n"
            f"except NameError:\n"
            f"    {model} = globals()['_pythonfmu_stand_in'] = type('S', (type('Fmi2Slave', (), {{'__module__': '_'}}),),\n"
            f"                                                      {{'__module__': '_'}})  # short reprs: what it leaks\n")


def _runtime_only(entries: dict[str, bytes], model: str, runtime: Runtime) -> dict[str, bytes]:
    """The run-time package's modules (its ``__init__.py`` without the builder), still under
    ``resources/<runtime>/``; PrivatiseError when they are not the expected ones."""
    source = f"resources/{runtime.name}/"
    shipped = {name[len(source):] for name in entries if name.startswith(source) and "__pycache__" not in name}
    missing = sorted(set(runtime.modules) - shipped)
    init = entries.get(f"{source}__init__.py", b"").decode()
    if missing or runtime.builder_import not in init:
        raise PrivatiseError(f"{model}: the {runtime.name} package in the FMU is not the expected one (missing "
                             f"{missing or [runtime.builder_import.strip()]}); greyfmu.privatise names what it needs")
    result = {source + module: entries[source + module] for module in runtime.modules}
    result[f"{source}__init__.py"] = init.replace(runtime.builder_import, "").encode()
    return result


def privatised_imports(source: str, embedded: frozenset[str], package: str, where: str) -> str:
    """``source`` with each absolute import of a top-level name in ``embedded`` naming
    ``package.<name>`` instead (``from greyfmu.x import y``, ``import greyfmu.x as z``, indented
    ones too).  A plain ``import greyfmu.x`` (which binds ``greyfmu``) cannot keep its meaning:
    PrivatiseError naming ``where`` and the line."""
    lines = source.splitlines(keepends=True)
    edits: list[tuple[int, int]] = []  # (row, column) of each top-level name to prefix
    tokens = [token for token in tokenize.generate_tokens(io.StringIO(source).readline)
              if token.type not in (tokenize.COMMENT, tokenize.NL)]
    for index, token in enumerate(tokens):
        if token.type != tokenize.NAME or token.string not in ("import", "from") or not _starts_statement(tokens, index):
            continue
        if token.string == "from":
            name = tokens[index + 1]
            if name.type == tokenize.NAME and name.string in embedded:
                edits.append(name.start)
            continue
        position = index + 1
        while True:  # import a.b [as c], d [as e], ...
            first, end = tokens[position], position
            while tokens[end + 1].string == ".":
                end += 2
            aliased = tokens[end + 1].string == "as"
            if first.string in embedded:
                if not aliased:
                    raise PrivatiseError(f"{where}, line {first.start[0]}: 'import {first.string}...' without 'as' "
                                         "cannot be moved under the FMU's private name: use 'from ... import' or 'as'")
                edits.append(first.start)
            position = end + (3 if aliased else 1)
            if tokens[position].string != ",":
                break
            position += 1
    for row, column in sorted(edits, reverse=True):
        line = lines[row - 1]
        lines[row - 1] = f"{line[:column]}{package}.{line[column:]}"
    return "".join(lines)


def _starts_statement(tokens: list[tokenize.TokenInfo], index: int) -> bool:
    previous = tokens[index - 1] if index > 0 else None
    return previous is None or previous.type in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
                                                 tokenize.ENCODING) or previous.string == ";"


def _check_no_public_import(source: str, embedded: frozenset[str], where: str) -> None:
    for node in ast.walk(ast.parse(source, where)):
        names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
            [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
        public = [name for name in names if name.split(".")[0] in embedded]
        if public:
            raise PrivatiseError(f"{where}, line {node.lineno}: still imports {public[0]} by its public name")


PRIVATE_PACKAGE = re.compile(rf"{PACKAGE_PREFIX}\w+_[0-9a-f]{{{HASH_DIGITS}}}")
"""What an FMU's private package name looks like (for the tests and the docs)."""
