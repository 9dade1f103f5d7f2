"""Shared fixtures."""

import os
from pathlib import Path

import pytest

from greyfmu.build import build_fmus


@pytest.fixture(scope="session")
def built_fmus() -> dict[str, Path]:
    """All FMUs of fmus/, built once per session into build/fmus (kept if up to date)."""
    return {path.stem: path for path in build_fmus()}


@pytest.fixture(autouse=True, scope="session")
def _repository_root() -> None:
    """Scenario paths in the tests (ssp/...) are relative to the repository root."""
    os.chdir(Path(__file__).resolve().parents[1])
