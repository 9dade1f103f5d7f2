"""The master's FMI 2.0 logger never formats blindly (issue 41, cosim/kernel/fmulog.c): a C FMU
logs printf formats with and without their arguments, then fails, so the messages the master kept
come back in the error.  At 5dbfe07 (fmpy's logger proxy: vsnprintf) the first message,
"%s%s%s%s%s%n%n%n 100%% end" sent without arguments, killed the run with SIGSEGV (in process:
`cosim run` lost its child; with --isolate the component was reported crashed)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from cfmus import build_c_fmu, fmi2_description

#: logged at the first doStep; the second returns Error
BODY = r"""
typedef void (*Logger)(void *env, const char *name, int status, const char *category, const char *message, ...);
typedef struct { Logger logger; void *allocate, *release, *finished; void *env; } Callbacks;
#define LOG(s, ...) ((const Callbacks *) (s)->callbacks)->logger(((const Callbacks *) (s)->callbacks)->env, \
                                                                 (s)->name, 0, "logAll", __VA_ARGS__)
static void start(S *s) {}
static void calculate(S *s) { s->r[1] = s->time; }
static int step(S *s, double t, double h) {
    if (t > 0) return 3;
    LOG(s, "%s%s%s%s%s%n%n%n 100%% end");
    LOG(s, "value %g at step %d of %s", 1.5, 3, "run");
    LOG(s, "%s", "an argument with %n in it");
    LOG(s, "50% done");
    LOG(s, "%s and %s", (const char *) 16, (const char *) 0);
    LOG(s, "%s%s%s%s%s no arguments");
    LOG(s, "%-6s;%5.2f;%x;%lld", "ab", 3.14159, 255, -1099511627776LL);
    return 0; }
"""

#: the kept lines, as the master shows them ("[OK] logAll: ...")
VERBATIM = ["%s%s%s%s%s%n%n%n 100%% end", "50% done", "%s and %s"]
FORMATTED = ["value 1.5 at step 3 of run", "an argument with %n in it", "ab    ; 3.14;ff;-1099511627776"]


@pytest.fixture(scope="module")
def talker(tmp_path_factory):
    description = fmi2_description("Talker", [("u", 0, "input", 0.0), ("y", 1, "output", None)], {"y": []},
                                   "{7a1c0000-0000-4000-8000-000000000041}")
    return build_c_fmu(tmp_path_factory.mktemp("talker"), "Talker", description, BODY)


def _run(fmu, tmp_path, *options, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(fmu), "--stop", "1", "--step", "0.5",
                           "--fmu-log", "all", "-o", str(tmp_path / "out.csv"), "-q", *options],
                          capture_output=True, text=True, timeout=120, env={**os.environ, **(env or {})})


@pytest.mark.parametrize("options", [[], ["--isolate"]], ids=["in-process", "isolated"])
def test_formats_only_what_it_safely_can(talker, tmp_path, options):
    done = _run(talker, tmp_path, *options)
    assert done.returncode == 1, done.stderr   # the FMU's own Error at t = 0.5, not a crash
    err = done.stderr
    assert "fmi2DoStep returned Error at t = 0.5" in err and "crashed" not in err, err
    kept = err.split(" FMU log: ", 1)[1].rstrip("\n").split(" | ")
    for text in VERBATIM + FORMATTED:
        assert f"[OK] logAll: {text}" in kept, (text, kept)
    # the argument-less %s: verbatim unless the register it reads happens to point at text
    assert any(line.endswith(" no arguments") for line in kept) and len(kept) == 7, kept


def test_without_the_compiled_library_every_message_is_verbatim(talker, tmp_path):
    """The fallback (no compiler at install): the Python callback receives the format itself."""
    done = _run(talker, tmp_path, env={"COSIM_KERNEL_LIBRARY": str(tmp_path / "missing.so")})
    assert done.returncode == 1, done.stderr
    kept = done.stderr.split(" FMU log: ", 1)[1].rstrip("\n").split(" | ")
    for text in VERBATIM + ["value %g at step %d of %s", "%s%s%s%s%s no arguments"]:
        assert f"[OK] logAll: {text}" in kept, (text, kept)
