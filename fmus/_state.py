"""A serialised FMU state (FMI 2.0 §2.1.8, fmi2SerializeFMUstate): its bytes, and reading them back
from a host.  Embedded in every FMI 2.0 FMU next to the slave base (fmus/_slave.py).

The bytes are `STATE_FORMAT` then a pickle (protocol 5) written by `StatePickler`, in one form on
every Python >= 3.10 and in every build of the same model:

- an enum member is written as its class called with its value (Python 3.11.0 to 3.11.4, Debian
  12's 3.11.2 among them, pickle one as ``getattr(class, name)``, the others as
  ``class(value)``): a state Debian's python3 saved restores under any other Python and back;
- a class of the FMU's own code (greyfmu's, the slave base's, the slave module's) is written by
  its name in the sources (``greyfmu.control.pid.PID``), not by the private name it is imported
  under inside the FMU (``_greyfmu_PID_<hash>.greyfmu.control.pid.PID``, greyfmu.privatise),
  as a persistent id ``("class", module, qualified name)``.

`StateUnpickler` reads them back from bytes a host passes in (fmi2DeSerializeFMUstate): a plain
``pickle.loads`` would call whatever the bytes name (``os.system``).  It resolves a persistent
class id only to a class of the FMU's own code, and a global only to one of `STATE_GLOBALS`
(numpy's arrays, scalars and random generators, a few builtins and collections); any other name,
bytes that are not a state (foreign, truncated, random, empty) and a state of another model are
refused with a ValueError naming what is wrong.
"""

from __future__ import annotations

import importlib
import io
import pickle
from enum import Enum
from typing import Any

STATE_FORMAT = b"greyfmu-fmu-state-2\n"
"""The first bytes of a serialised FMU state.  Format 1 (until issue 39) named classes by the
modules they were imported from and enum members as the Python that wrote them did."""

OWN_CODE = ("greyfmu", "_slave")
"""The top-level modules of the FMU's own code whose classes a state may name, with the slave's module."""

STATE_GLOBALS = frozenset(
    [("builtins", name) for name in ("complex", "set", "frozenset", "slice", "range", "bytearray")]
    + [("collections", "deque"), ("collections", "OrderedDict"), ("numpy", "dtype"), ("numpy", "ndarray")]
    + [(f"numpy.{core}.{module}", name) for core in ("core", "_core")
       for module, name in (("multiarray", "_reconstruct"), ("multiarray", "scalar"), ("numeric", "_frombuffer"))]
    + [("numpy.random._pickle", name) for name in ("__generator_ctor", "__bit_generator_ctor", "__randomstate_ctor")]
    + [(f"numpy.random.{module}", name) for module, name in (
        ("_pcg64", "PCG64"), ("_pcg64", "PCG64DXSM"), ("_mt19937", "MT19937"), ("_philox", "Philox"),
        ("_sfc64", "SFC64"), ("mtrand", "RandomState"), ("bit_generator", "SeedSequence"),
        ("bit_generator", "__pyx_unpickle_SeedSequence"))])
"""The other globals a serialised state may name: what pickle writes for our states' builtins,
deques, numpy arrays, scalars and random generators (numpy 1.x's ``numpy.core`` and 2.x's ``numpy._core``)."""

PACKAGE = __name__.rpartition(".")[0]
"""The FMU's private package ('' where this module runs under its own name: a build, the tests)."""


def source_name(module: str) -> str | None:
    """The name in the sources of ``module``, a module of the FMU's own code imported under the
    private package; None for any other module (numpy's, the standard library's)."""
    if PACKAGE:
        return module[len(PACKAGE) + 1:] if module.startswith(PACKAGE + ".") else None
    return module


class StatePickler(pickle.Pickler):
    """Writes a state in the form described in the module docstring."""

    def __init__(self, file: io.BytesIO, slave_module: str) -> None:
        super().__init__(file, protocol=5)
        self._own = (*OWN_CODE, slave_module)

    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, Enum):
            return type(obj), (obj._value_,)
        return NotImplemented

    def persistent_id(self, obj: Any) -> tuple[str, str, str] | None:
        if not isinstance(obj, type):
            return None
        module = source_name(obj.__module__)
        if module is None or module.split(".")[0] not in self._own:
            return None
        return "class", module, obj.__qualname__


class StateUnpickler(pickle.Unpickler):
    """Reads a state `StatePickler` wrote; refuses any other name (see the module docstring)."""

    def __init__(self, data: bytes, slave_module: str) -> None:
        super().__init__(io.BytesIO(data))
        self._slave_module = slave_module
        self._own = (*OWN_CODE, slave_module)

    def persistent_load(self, pid: Any) -> type:
        if not (isinstance(pid, tuple) and len(pid) == 3 and pid[0] == "class" and all(isinstance(p, str) for p in pid)):
            raise pickle.UnpicklingError(f"a serialised FMU state of {self._slave_module} holds a persistent id {pid!r}")
        _, module, qualified = pid
        if module.split(".")[0] not in self._own or not all(part.isidentifier() for part in (*module.split("."),
                                                                                               *qualified.split("."))):
            raise pickle.UnpicklingError(f"a serialised FMU state of {self._slave_module} may not refer to "
                                         f"{module}.{qualified}")
        found: Any = importlib.import_module(f"{PACKAGE}.{module}" if PACKAGE else module)
        for part in qualified.split("."):
            found = getattr(found, part, None) if not part.startswith("__") else None
        defined_in = source_name(getattr(found, "__module__", "")) or ""
        if not isinstance(found, type) or defined_in.split(".")[0] not in self._own:
            raise pickle.UnpicklingError(f"a serialised FMU state of {self._slave_module} refers to {module}.{qualified}, "
                                         "which is not a class of this FMU's code")
        return found

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in STATE_GLOBALS:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"a serialised FMU state of {self._slave_module} may not refer to {module}.{name}")


def state_bytes(state: dict[str, Any], slave_module: str) -> bytes:
    """`STATE_FORMAT` then ``state`` pickled by `StatePickler`."""
    buffer = io.BytesIO()
    buffer.write(STATE_FORMAT)
    StatePickler(buffer, slave_module).dump(state)
    return buffer.getvalue()


def state_from_bytes(data: bytes, model: str, slave_module: str) -> dict[str, Any]:
    """The state of ``model`` that `state_bytes` wrote; ValueError saying why when ``data`` is
    not one (another format, not a pickle, truncated, a name it may not refer to, another model)."""
    what = f"the {len(data)} bytes given are not a serialised state of {model}"
    if not data.startswith(STATE_FORMAT):
        older = data.startswith(b"greyfmu-fmu-state-")
        raise ValueError(f"{what}: they do not start with {STATE_FORMAT!r}"
                         + (" (a state of an older format: save it again with this FMU)" if older else ""))
    try:
        state = StateUnpickler(data[len(STATE_FORMAT):], slave_module).load()
    except Exception as error:  # every way bytes can fail to unpickle: UnpicklingError, EOFError, ValueError, ...
        raise ValueError(f"{what}: {type(error).__name__}: {error}") from None
    if not isinstance(state, dict) or state.get("model") != model or not isinstance(state.get("attributes"), dict):
        other = state.get("model") if isinstance(state, dict) else type(state).__name__
        raise ValueError(f"{what}: they hold a state of {other!r}")
    return state
