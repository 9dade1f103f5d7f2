"""fmpy's FMU classes with the FMI function table built once per class, not once per instance.

fmpy's ``_FMU._loadFunctions`` finds the FMI functions of an instance by ``inspect.getmembers``
and ``inspect.signature`` of every method, for every instance: most of what loading a native
FMU costs (issue 28: 0.7 ms of a 10-FMU system's 1 ms per FMU).  `quick` gives a subclass that
reads the same table (name, argument names and types, result type) from the class once and
looks the C functions up once per loaded library: the instances of one FMU file share its
function objects while one of them holds the library (each instance's dlopen counts; its
``freeLibrary`` drops the shared table with the last of them, so a library loaded again, maybe
elsewhere in memory, is looked up again).  The look-ups were 0.86 ms an instance (36 ctypes
functions, issue 42).
"""
from __future__ import annotations

import ctypes
import inspect
import threading
import types
import typing
from functools import cache

#: (method name, argument names, argument types, result type) of an fmpy FMU class
Table = tuple[tuple[str, tuple[str, ...], tuple, object], ...]


def _prefix(cls: type) -> str:
    name = cls.__name__
    return "fmi2" if name.startswith("FMU2") else "fmi3"


@cache
def _table(cls: type) -> Table:
    """What fmpy's ``_loadFunctions`` derives from the methods of ``cls`` (FMI 2.0 and 3.0 classes)."""
    rows = []
    for name, method in inspect.getmembers(cls, inspect.isfunction):
        if not name.startswith(_prefix(cls)):
            continue
        params = list(inspect.signature(method).parameters.values())[1:]   # without self
        argtypes = tuple(typing.get_args(p.annotation)[0] if isinstance(p.annotation, types.UnionType)
                         else p.annotation for p in params)
        restype = inspect.signature(method).return_annotation
        restype = ctypes.c_char_p if restype is bytes else ctypes.c_int if restype is int else restype
        rows.append((name, tuple(p.name for p in params), argtypes, restype))
    return tuple(rows)


#: per (fmpy class, library path): its FMI functions and how many instances hold the library
_shared: dict[tuple[type, str], tuple[dict[str, object], list[int]]] = {}
_shared_lock = threading.Lock()


@cache
def quick(cls: type) -> type:
    """``cls`` (an fmpy FMU2/FMU3 class) whose instances load their FMI functions from `_table`,
    once per loaded library (`_shared`)."""
    def _loadFunctions(self) -> None:
        key = (cls, self.dll._name)
        with _shared_lock:
            if key not in _shared:
                functions = {}
                for name, argnames, argtypes, restype in _table(cls):
                    c_fun = getattr(self.dll, name)
                    c_fun.argnames = list(argnames)
                    c_fun.argtypes = list(argtypes)
                    c_fun.restype = restype
                    functions[name] = c_fun
                _shared[key] = (functions, [0])
            functions, holders = _shared[key]
            holders[0] += 1
        self._functions.update(functions)
        self._shared_key = key

    def freeLibrary(self) -> None:
        with _shared_lock:
            entry = _shared.get(getattr(self, "_shared_key", None))
            if entry is not None:
                entry[1][0] -= 1
                if entry[1][0] == 0:
                    del _shared[self._shared_key]
            self._shared_key = None
            cls.freeLibrary(self)

    return type(cls.__name__, (cls,), {"_loadFunctions": _loadFunctions, "freeLibrary": freeLibrary,
                                       "__module__": __name__, "__doc__": f"{cls.__name__} with `quick` loading."})
