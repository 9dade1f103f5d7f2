"""Can this Python run the FMU?  Shipped as ``resources/greyfmu_target.py`` of every greyfmu FMU.

The FMU's loader (``greyfmu/loader/fmi2_loader.c``) runs this file twice: as a script in a
child process (``python greyfmu_target.py --query``) to learn where a candidate interpreter's
shared libpython, home and ``sys.path`` are, and inside the host process once Python runs there.
Either way it leaves ``problem``: an empty string, or one sentence naming what is missing and
how to fix it.  It checks the Python version (3.10 or newer) and that every module named in
``greyfmu_requirements.txt`` next to it imports.

It must itself run on old Pythons to say they are too old, so it uses no syntax newer than 3.6.
"""

import os
import sys
import sysconfig

MINIMUM = (3, 10)
HERE = os.path.dirname(os.path.abspath(__file__))
FIX = "set GREYFMU_PYTHON to a Python 3.10+ that has numpy and scipy (see the FMU's documentation/index.html)"


def requirements():
    """The modules the FMU's embedded code imports from the target Python."""
    with open(os.path.join(HERE, "greyfmu_requirements.txt")) as listing:
        return [line.strip() for line in listing if line.strip()]


def missing_modules(names):
    """The names of ``names`` that do not import, each with the error's first line."""
    missing = []
    for name in names:
        try:
            __import__(name)
        except Exception as error:  # any failure to import is a missing requirement
            missing.append("{} ({}: {})".format(name, type(error).__name__, str(error).splitlines()[0] if str(error) else ""))
    return missing


def shared_libpython():
    """The path of this interpreter's shared libpython (Windows: pythonXY.dll), or None if it has none."""
    if os.name == "nt":
        import _winapi

        return _winapi.GetModuleFileName(sys.dllhandle)
    names = [sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY"),
             "libpython{}.{}.so.1.0".format(*sys.version_info[:2])]
    folders = [sysconfig.get_config_var("LIBDIR"), os.path.join(sys.base_prefix, "lib")]
    multiarch = sysconfig.get_config_var("MULTIARCH")
    if multiarch:
        folders.append(os.path.join("/usr/lib", multiarch))
    for folder in folders:
        for name in names:
            if folder and name and name.endswith((".so", ".so.1.0")) and os.path.isfile(os.path.join(folder, name)):
                return os.path.join(folder, name)
    return None


def stable_abi_library():
    """Windows: python3.dll next to pythonXY.dll (pythonfmu's DLL imports it); '' elsewhere."""
    if os.name != "nt":
        return ""
    return os.path.join(os.path.dirname(shared_libpython()), "python3.dll")


def check(query):
    """The problem sentence ('' when the FMU can run here)."""
    executable = sys.executable or "the host's Python"
    if sys.version_info[:2] < MINIMUM:
        return "{} is Python {}.{}, older than 3.10: {}".format(executable, sys.version_info[0], sys.version_info[1], FIX)
    if query and shared_libpython() is None:  # (always found on Windows)
        return ("{} has no shared libpython (it was built without --enable-shared; Debian: apt-get install "
                "libpython3-dev; pyenv: PYTHON_CONFIGURE_OPTS=--enable-shared pyenv install): {}").format(executable, FIX)
    missing = missing_modules(requirements())
    if missing:
        names = [entry.split(" ")[0] for entry in missing]
        hint = install_hint(names)
        return "{} cannot import {}: {}".format(executable, ", ".join(missing),
                                                hint if "GREYFMU_PYTHON" in hint else hint + ", or " + FIX)
    return ""


DEBIAN_PACKAGES = {"numpy": "python3-numpy", "scipy": "python3-scipy"}
"""The Debian/Ubuntu packages of the requirements that have one (daqp has none)."""


def externally_managed():
    """Whether pip refuses to install into this interpreter (PEP 668: an EXTERNALLY-MANAGED file in
    its standard library folder, outside a virtual environment): Debian's and Ubuntu's python3."""
    if sys.prefix != sys.base_prefix:
        return False
    stdlib = sysconfig.get_path("stdlib")
    return bool(stdlib) and os.path.isfile(os.path.join(stdlib, "EXTERNALLY-MANAGED"))


def install_hint(names):
    """How to install the missing modules ``names`` into a Python the FMU can use: pip where pip may
    install, else Debian's packages (when they cover them) or a virtual environment."""
    executable = sys.executable or "python3"
    if not externally_managed():
        return "install with `{} -m pip install {}`".format(executable, " ".join(names))
    venv = ("make a virtual environment with them (`{} -m venv ~/fmu-python && ~/fmu-python/bin/python -m pip install "
            "{}`) and set GREYFMU_PYTHON=~/fmu-python/bin/python").format(executable, " ".join(names))
    if all(name in DEBIAN_PACKAGES for name in names):
        return "install Debian's packages (`sudo apt-get install {}`; pip refuses this externally managed Python), " \
               "or {}".format(" ".join(DEBIAN_PACKAGES[name] for name in names), venv)
    return "this Python is externally managed (pip refuses it): {}".format(venv)


def loader_bytes(text):
    """``text`` as the loader's C strings hold it: POSIX, the file system's bytes (os.fsencode: a
    path need not be UTF-8); Windows, the ANSI code page of its ...A functions."""
    return os.fsencode(text) if os.name != "nt" else text.encode("mbcs", "replace")


problem = check(query=__name__ == "__main__")

if __name__ == "__main__":
    for key, value in [("problem", problem), ("version", sys.version.split()[0]), ("executable", sys.executable),
                       ("libpython", shared_libpython() or ""), ("stable_abi", stable_abi_library()),
                       ("home", sys.base_prefix if sys.base_prefix == sys.base_exec_prefix
                        else sys.base_prefix + os.pathsep + sys.base_exec_prefix),
                       ("path", ascii([entry for entry in sys.path if os.path.abspath(entry) != HERE]))]:
        sys.stdout.buffer.write(b"greyfmu-" + key.encode("ascii") + b"=" + loader_bytes(value.replace("\n", " ")) + b"\n")
