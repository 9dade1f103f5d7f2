"""Build the test-only FMUs of tests/fmus/ with pythonfmu (real FMUs, not mocks), and the
FMI 3.0 ones of tests/fmus/fmi3/ with pythonfmu3 (`build_test_fmus3`); `edited_copy` needs
neither, so pythonfmu is imported only by the builders (tests/cosim runs without it)."""
from __future__ import annotations

import zipfile
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).parent / "fmus"


def build_test_fmus(dest: Path) -> dict[str, Path]:
    from pythonfmu.builder import FmuBuilder

    dest.mkdir(parents=True, exist_ok=True)
    return {script.stem: Path(FmuBuilder.build_FMU(script, dest=dest, needsExecutionTool="false"))
            for script in sorted(HERE.glob("*.py"))}


def build_test_fmus3(dest: Path) -> dict[str, Path]:
    from pythonfmu3.builder import FmuBuilder as Fmu3Builder

    dest.mkdir(parents=True, exist_ok=True)
    return {script.stem: Path(Fmu3Builder.build_FMU(script, dest=dest))
            for script in sorted((HERE / "fmi3").glob("*.py"))}


def edited_copy(source: Path, target: Path, edit: Callable[[str], str]) -> Path:
    """The same FMU (binaries unchanged) with ``edit`` applied to its modelDescription.xml
    text, written to ``target`` (which may be ``source`` itself)."""
    with zipfile.ZipFile(source) as archive:
        members = [(info, archive.read(info)) for info in archive.infolist()]
    target.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for info, data in members:
            if info.filename == "modelDescription.xml":
                data = edit(data.decode("utf-8")).encode("utf-8")
            archive.writestr(info, data)
    return target
