"""The loader never writes the process's environment (issue 29): a host may read it from other
threads at any time (getenv is not safe against a concurrent setenv), so the candidate Python's
home goes to Py_SetPythonHome, never to setenv(PYTHONHOME).  Checked on the compiled loader of each
platform whose compiler is here: none of the C library's environment writers is imported."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from greyfmu.loader import PLATFORMS, compiler, loader_binary

#: the functions that change the environment, by platform folder (glibc; the MSVC runtime and kernel32)
WRITERS = {"linux64": {"setenv", "putenv", "unsetenv", "clearenv"},
           "win64": {"_putenv", "_putenv_s", "_wputenv", "_wputenv_s", "SetEnvironmentVariableA",
                     "SetEnvironmentVariableW", "SetEnvironmentStringsW"}}
#: the tool that lists a library's imported functions, and how to read its lines
LISTERS = {"linux64": ("nm", ["-D", "--undefined-only"]), "win64": ("x86_64-w64-mingw32-objdump", ["-p"])}


def imported_functions(folder: str, library: Path) -> set[str]:
    tool, options = LISTERS[folder]
    if shutil.which(tool) is None:
        pytest.skip(f"{tool} is not on PATH")
    listed = subprocess.run([tool, *options, str(library)], capture_output=True, text=True, check=True).stdout
    return {word.split("@")[0] for line in listed.splitlines() for word in line.split()}


@pytest.mark.parametrize("platform", PLATFORMS, ids=lambda p: p.folder)
def test_the_loader_imports_no_function_that_writes_the_environment(platform, tmp_path):
    if compiler(platform) is None:
        pytest.skip(f"no {platform.compilers[0]} on PATH")
    library = tmp_path / f"loader{platform.suffix}"
    library.write_bytes(loader_binary(platform))
    imported = imported_functions(platform.folder, library)
    assert "getenv" in imported          # the listing works: the loader reads GREYFMU_PYTHON
    assert imported & WRITERS[platform.folder] == set()
