"""An FMU of ours in a process it shares: with the host's own packages, other FMUs of ours (any
release), other vendors' pythonfmu FMUs.  Embedded in every FMU (FMI 2.0 and 3.0) next to the
slave base.

Inside an FMU this module is ``<package>._inprocess``, where ``<package>`` is the FMU's private
package (``_greyfmu_<model>_<hash>``, greyfmu.privatise): every module the FMU embeds lives
under it.  pythonfmu and pythonfmu3 insert the FMU's ``resources/`` at the front of ``sys.path``
at each instantiation to import the slave module; once it is imported that entry serves no one
and would stay in the host for ever (one per run of fmpy.simulate_fmu, each in a folder fmpy
deletes); both insert a new str they never release (PyUnicode_FromString).  `settle_imports`, called by the slave base's ``__init__``, takes it off and points the
private package (and its subpackages) at this instance's folder, first: a submodule imported
later (a lazy import) is found in a folder that exists even when the folder the package was
first imported from has been deleted since (fmpy extracts each run into a new one).

`give_back` keeps an instance alive after one of its calls raised: pythonfmu 0.7.0 and
pythonfmu3 0.3.4 answer a Python exception by releasing the instance, its class and its log
queue (PySlaveInstance.cpp, handle_py_exception calls cleanPyObject) and release them again when
the instance is freed (~PySlaveInstance), which frees objects still in use; each reference they
release without owning it is given back first (``Py_IncRef``, owned by no one, as the released
one was; a Python list holding them would own its references and they would still be freed
under it).
"""

from __future__ import annotations

import ctypes
import os
import sys

PACKAGE = __name__.rpartition(".")[0]
"""The FMU's private package; '' where this module runs under its own name (a build, the tests)."""


def settle_imports(resources: str | None) -> None:
    """Take ``resources`` off the front of ``sys.path`` (where pythonfmu has just inserted it) and
    point the private package at ``resources/<package>`` (see the module docstring)."""
    if not PACKAGE or resources is None:
        return
    if sys.path and sys.path[0] == resources:  # only pythonfmu's entry: after fmi2Reset there is none
        entry = sys.path.pop(0)
        sys.path_importer_cache.pop(entry, None)
        if sys.getrefcount(entry) == 3:  # the argument, `entry`, and the reference pythonfmu never releases
            ctypes.pythonapi.Py_DecRef(ctypes.py_object(entry))
    point_package_at(resources)


def point_package_at(resources: str) -> None:
    """Make ``resources/<package>`` (and its subfolders) the first place the private package and
    its subpackages import from, dropping folders that no longer exist (also called by the FMI
    2.0 loader before each instantiation, fmi2_loader.c PREPARE_INSTANCE)."""
    folder = os.path.join(resources, PACKAGE)
    if sys.modules[PACKAGE].__path__[:1] == [folder]:
        return
    for name, module in list(sys.modules.items()):
        path = getattr(module, "__path__", None)
        if path is None or not (name == PACKAGE or name.startswith(PACKAGE + ".")):
            continue
        here = os.path.join(folder, *name.split(".")[1:])
        dead = [entry for entry in path if entry != here and not os.path.isdir(entry)]
        for entry in dead:
            sys.path_importer_cache.pop(entry, None)
        path[:] = [here] + [entry for entry in path if entry != here and entry not in dead]


def give_back(*objects: object) -> None:
    """One reference to each of ``objects`` that no one owns (see the module docstring)."""
    for item in objects:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(item))
