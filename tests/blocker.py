"""pythonfmu, pythonfmu3 and greyfmu.build made unimportable, as on a machine with only the master
installed: in this process (`blocked`, around each test of tests/cosim: tests/cosim/conftest.py)
and in the processes it starts (a ``sitecustomize.py`` on their ``PYTHONPATH``, `environment`)."""
from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

BLOCKED = ("pythonfmu", "pythonfmu3", "greyfmu.build")

#: the sitecustomize.py of a child process
SITECUSTOMIZE = f'''"""Make {", ".join(BLOCKED)} unimportable (tests/blocker.py)."""
import sys

BLOCKED = {BLOCKED!r}


class Blocker:
    def find_spec(self, name, path=None, target=None):
        if any(name == b or name.startswith(b + ".") for b in BLOCKED):
            raise ImportError(f"{{name}} is blocked by tests/blocker.py")
        return None


sys.meta_path.insert(0, Blocker())
'''


def is_blocked(name: str) -> bool:
    return any(name == b or name.startswith(b + ".") for b in BLOCKED)


class Blocker:
    """A meta path finder that refuses the blocked modules."""

    def find_spec(self, name, path=None, target=None):
        if is_blocked(name):
            raise ImportError(f"{name} is blocked by tests/blocker.py")
        return None


def environment(folder: Path, env: dict[str, str] | None = None) -> dict[str, str]:
    """``env`` (default: this process's) for a child process in which the modules are blocked."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sitecustomize.py").write_text(SITECUSTOMIZE)
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join([str(folder), *filter(None, [env.get("PYTHONPATH")])])
    return env


@contextlib.contextmanager
def blocked():
    """The modules unimportable in this process: the imported ones hidden from ``sys.modules`` (and
    from their packages' attributes), a `Blocker` first on ``sys.meta_path``; all put back after."""
    hidden = {name: sys.modules.pop(name) for name in list(sys.modules) if is_blocked(name)}
    attributes = []
    for name in hidden:
        parent, _, child = name.rpartition(".")
        if parent in sys.modules and getattr(sys.modules[parent], child, None) is hidden[name]:
            attributes.append((sys.modules[parent], child, hidden[name]))
            delattr(sys.modules[parent], child)
    finder = Blocker()
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        for name in [n for n in sys.modules if is_blocked(n)]:   # imported anyway (it cannot be): dropped
            del sys.modules[name]
        sys.modules.update(hidden)
        for owner, child, module in attributes:
            setattr(owner, child, module)
