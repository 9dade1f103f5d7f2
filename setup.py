"""The compiled stepping loop (cosim/kernel/kernel.c), CSV row formatter (cosim/kernel/csvrows.c,
with the vendored Ryu in cosim/kernel/ryu) and FMI 2.0 logger (cosim/kernel/fmulog.c), built when greyfmu
is installed.

An optional extension: without a C compiler the install still succeeds and cosim runs its
Python loop (same results, one notice) and formats result CSVs in Python (same bytes, slower).
The library uses no Python C API; cosim.kernel loads it with ctypes.  -ffp-contract=off keeps y * factor + offset two roundings, as NumPy's.
Warnings are shown (-Wall -Wextra) but fail the build only in our CI (.ci/run sets GREYFMU_WERROR=1,
which also makes the extension required there, so a warning cannot turn into a silent fallback);
a user's newer compiler adding a warning does not break an install.
Everything else about the package is in pyproject.toml.
"""
import os

from setuptools import Extension, setup

STRICT = os.environ.get("GREYFMU_WERROR") == "1"

setup(ext_modules=[Extension("cosim.kernel._kernel", sources=["cosim/kernel/kernel.c", "cosim/kernel/csvrows.c",
                                                                      "cosim/kernel/fmulog.c"],
                             include_dirs=["cosim/kernel"], optional=not STRICT,
                             extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math", "-pthread", "-Wall",
                                                 "-Wextra", *(["-Werror"] if STRICT else [])],
                             extra_link_args=["-pthread"])])
