"""tests/cosim runs with only what it tests (issues 29, 40): pythonfmu, pythonfmu3 and greyfmu.build
are unimportable around each of its tests, in this process and in the processes a test starts
(tests/blocker.py), as on a machine with only the master installed; a test marked
``@pytest.mark.pythonfmu`` (a master feature shown on our FMUs or a pythonfmu FMU of tests/fmus)
runs without the blocker."""
from __future__ import annotations

import pytest

from blocker import blocked, environment


@pytest.fixture(autouse=True)
def _without_pythonfmu(request, monkeypatch, tmp_path_factory):
    if request.node.get_closest_marker("pythonfmu") is not None:
        yield
        return
    if "built_fmus" in request.fixturenames:   # a session fixture, made before the blocker: it needs the mark
        pytest.fail("built_fmus builds our FMUs with pythonfmu: mark the test @pytest.mark.pythonfmu")
    for name, value in environment(tmp_path_factory.mktemp("blocker")).items():
        if name == "PYTHONPATH":
            monkeypatch.setenv(name, value)
    with blocked():
        yield
