"""fmpy's FMU classes with the FMI function table built once per class, not once per instance.

fmpy's ``_FMU._loadFunctions`` finds the FMI functions of an instance by ``inspect.getmembers``
and ``inspect.signature`` of every method, for every instance: most of what loading a native
FMU costs (issue 28: 0.7 ms of a 10-FMU system's 1 ms per FMU).  `quick` gives a subclass that
reads the same table (name, argument names and types, result type) from the class once, and
loads each library once (`_SharedLibrary`): the instances of one FMU file share its ctypes
library and function objects while one of them holds it; the last ``freeLibrary`` unloads it,
so a library loaded again, maybe elsewhere in memory, is looked up again.  A ctypes library and
36 look-ups per instance were most of an instance's 1 ms in a system of 1000 (issue 42).
"""
from __future__ import annotations

import ctypes
import inspect
import os
import threading
import types
import typing
from functools import cache

from fmpy import platform, sharedLibraryExtension
from fmpy.fmi1 import _FMU

#: (method name, argument names, argument types, result type) of an fmpy FMU class
Table = tuple[tuple[str, tuple[str, ...], tuple, object], ...]


def _prefix(cls: type) -> str:
    name = cls.__name__
    return "fmi2" if name.startswith("FMU2") else "fmi3"


@cache
def _table(cls: type) -> Table:
    """What fmpy's ``_loadFunctions`` derives from the methods of ``cls`` (FMI 2.0 and 3.0 classes)."""
    rows = []
    prefix = _prefix(cls)
    for name in sorted(n for n in dir(cls) if n.startswith(prefix)):
        method = getattr(cls, name)
        if not inspect.isfunction(method):
            continue
        # the signature from the code object and annotations (inspect.signature: 1.5 ms a class)
        code, annotations = method.__code__, method.__annotations__
        params = code.co_varnames[1:code.co_argcount]   # without self
        argtypes = tuple(typing.get_args(a)[0] if isinstance(a, types.UnionType) else a
                         for a in (annotations.get(p, inspect.Parameter.empty) for p in params))
        restype = annotations.get("return", inspect.Signature.empty)
        restype = ctypes.c_char_p if restype is bytes else ctypes.c_int if restype is int else restype
        rows.append((name, tuple(params), argtypes, restype))
    return tuple(rows)


#: per `quick` class and library path: the library (loaded once), its FMI functions, how many
#: instances hold it, and which other symbols it was asked for (`exports`)
_shared: dict[tuple[type, str], tuple[ctypes.CDLL, dict[str, object], list[int], dict[str, bool]]] = {}
_shared_lock = threading.Lock()


class _SharedLibrary(_FMU):
    """fmpy's ``_FMU`` whose library is loaded by the first instance of a path (fmpy's own
    ``__init__``: the library's folder as working folder while it loads, `_table`'s look-ups) and
    shared by the instances after it, until the last of them frees it: a ctypes library made per
    instance (a class and a dlopen each) and 36 look-ups were most of an instance's 1 ms."""

    def __init__(self, guid, modelIdentifier, unzipDirectory, instanceName=None, libraryPath=None,
                 fmiCallLogger=None, requireFunctions=True):
        if libraryPath is None:   # as fmpy makes it (an FMI 3.0 class gives it)
            libraryPath = os.path.join(os.path.abspath(os.path.join(unzipDirectory, "binaries", platform)),
                                       modelIdentifier + sharedLibraryExtension)
        key = (type(self), str(libraryPath))
        with _shared_lock:
            entry = _shared.get(key)
            if entry is None:
                _FMU.__init__(self, guid=guid, modelIdentifier=modelIdentifier, unzipDirectory=unzipDirectory,
                              instanceName=instanceName, libraryPath=libraryPath, fmiCallLogger=fmiCallLogger,
                              requireFunctions=requireFunctions)
                entry = _shared[key] = (self.dll, dict(self._functions), [0], {})
            else:
                self.guid, self.modelIdentifier, self.unzipDirectory = guid, modelIdentifier, unzipDirectory
                self.instanceName = instanceName if instanceName is not None else modelIdentifier
                self.fmiCallLogger, self.requireFunctions = fmiCallLogger, requireFunctions
                self.dll, self._functions = entry[0], dict(entry[1])
                self.component, self.callbacks = None, None
            entry[2][0] += 1
            self._shared_key = key

    def _loadFunctions(self) -> None:
        for name, argnames, argtypes, restype in _table(type(self).__mro__[1]):
            c_fun = getattr(self.dll, name)
            c_fun.argnames = list(argnames)
            c_fun.argtypes = list(argtypes)
            c_fun.restype = restype
            self._functions[name] = c_fun

    def freeLibrary(self) -> None:
        """Unload the library with the last instance holding it (an instance freed twice frees once)."""
        with _shared_lock:
            key = getattr(self, "_shared_key", None)
            if key is None:
                return
            self._shared_key = None
            entry = _shared[key]
            entry[2][0] -= 1
            if entry[2][0] == 0:
                del _shared[key]
                _FMU.freeLibrary(self)


@cache
def quick(cls: type) -> type:
    """``cls`` (an fmpy FMU2/FMU3 class) whose instances load their FMI functions from `_table`,
    sharing one load of each library (`_SharedLibrary`)."""
    return type(cls.__name__, (cls, _SharedLibrary), {"__module__": __name__,
                                                      "__doc__": f"{cls.__name__} with `quick` loading."})


def exports(slave, symbol: str) -> bool:
    """Whether the library of ``slave`` (an fmpy FMU instance) exports ``symbol``: looked up once
    per loaded library for a `quick` class's instances (a symbol it lacks costs a failed dlsym and
    an exception each time), else each time."""
    entry = _shared.get(getattr(slave, "_shared_key", None))
    if entry is None:
        return hasattr(slave.dll, symbol)
    found = entry[3]
    if symbol not in found:
        found[symbol] = hasattr(slave.dll, symbol)
    return found[symbol]
