#!/usr/bin/env bash
# The test command (README command 2): uses the active virtual environment, else .venv/ (made
# with python3, or python, if missing: Debian and Ubuntu refuse pip installs into their own
# Python), installs the project with its test tools and the third-party FMUs from the registry,
# then runs the whole suite, a file to a worker on every core (pytest-xdist: 728 s on 2 cores against
# 1215 s in one process; GREYFMU_TEST_WORKERS=0 runs it in one). Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${VIRTUAL_ENV:-}" ]; then
    if [ ! -x .venv/bin/python ]; then
        PY=$(command -v python3 || command -v python) || { echo "tests/run.sh: no python3 or python on PATH" >&2; exit 2; }
        "$PY" -m venv .venv
    fi
    . .venv/bin/activate
fi
python -m pip install --quiet --disable-pip-version-check -e ".[test]"
# OpenModelica-exported FMUs; --no-deps keeps gemseo itself (heavy) out.
python -m pip install --quiet --disable-pip-version-check --no-deps gemseo-fmu==3.1.1
python -m pytest -q -n "${GREYFMU_TEST_WORKERS:-auto}" --dist loadfile "$@"
