"""Build the test-only FMUs of tests/fmus/ with pythonfmu (real FMUs, not mocks)."""
from __future__ import annotations

from pathlib import Path

from pythonfmu.builder import FmuBuilder

HERE = Path(__file__).parent / "fmus"


def build_test_fmus(dest: Path) -> dict[str, Path]:
    dest.mkdir(parents=True, exist_ok=True)
    return {script.stem: Path(FmuBuilder.build_FMU(script, dest=dest, needsExecutionTool="false"))
            for script in sorted(HERE.glob("*.py"))}
