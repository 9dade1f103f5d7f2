"""pytest plugin (``pytest11`` entry point): regression fixtures for co-simulation scenarios.

Installing the ``greyfmu`` distribution registers this plugin with pytest; no conftest.py
is needed.  A test runs a scenario and compares it, signal by signal and sample by sample,
with a stored reference CSV::

    def test_pid_loop(cosim_regression):
        result = cosim_regression("ssp/pid_fopdt", stop=60.0,
                                  signals=["plant.y", "controller.u"],
                                  tolerances={"controller.*": (1e-5, 1e-8)})
        # ``result`` is the run's structured array (every connector), for further checks

The first run fails: the reference does not exist yet.  Write it (and rewrite it after an
intended change) with ``pytest --cosim-update-references``; those tests pass and the
terminal summary lists the files written.  Commit the references with the tests.

``cosim_regression(scenario, *, reference=None, stop=None, step=None, param_sets=(),
fmu_dirs=(), signals=None, tolerances=None, rtol=1e-6, atol=1e-9, decimate=None)``

- ``scenario``: scenario folder, ``.ssd`` or ``.ssp`` (relative paths are taken from the
  current directory, as ``cosim run`` takes them).
- ``reference``: the CSV's file name in the references folder: by default beside the test
  file, in a folder named after it (``tests/test_loop.py`` -> ``tests/test_loop/``, as
  pytest-regressions keeps its data), or the folder the ini option ``cosim_references``
  names, relative to the rootdir, or the folder a conftest's own ``cosim_references_dir``
  fixture returns (this repository's tests/conftest.py: ``tests/references``); a path
  (``sub/x.csv``, ``../x.csv``, ``/abs/x.csv``) fails the test, so no test writes outside the
  folder.  References are written in one rename (`cosim.record.results.write`).
  Default: ``<test name>.csv`` there (parametrised tests: ``test_x[id].csv``, characters
  other than letters, digits, ``_.-[]`` replaced by ``_``).
- ``stop``, ``step``, ``param_sets``, ``fmu_dirs``: as for ``cosim.simulate``.
- ``signals``: globs selecting the compared (and stored) signals, default every connector.
- ``tolerances``: ``{glob: (rtol, atol) or {"rtol": .., "atol": ..}}``; the most specific key
  matching a signal wins (`cosim.present.metrics.tolerance_for`), others get ``rtol``/``atol``.  A
  sample passes when |candidate − reference| <= atol + rtol·|reference|.
- ``decimate``: keep every n-th sample (first included) in the reference and the comparison,
  to keep long references small.

The test fails when the grids differ (saying how), when a reference signal is not produced
(or a selected one is not in the reference), or when a signal leaves its band: the message
lists each failing signal with the first failing time, value, reference, difference and
tolerance, the reference's path and where the candidate was written (every connector of the
run, in the test's ``tmp_path``).  A run error or an invalid scenario fails the test with
cosim's message.  The comparison is `cosim.present.metrics.compare`, the same as ``cosim compare``.

The module imports nothing but pytest at import time (cosim, NumPy and fmpy are imported
when the fixture is first called), since pytest loads it into every session.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import pytest

if TYPE_CHECKING:
    import numpy as np

    from .present.metrics import ToleranceSpec

UPDATE_OPTION = "--cosim-update-references"
REFERENCES_INI = "cosim_references"

#: (node id, reference path, "written" or "rewritten"), listed in the terminal summary
_WRITTEN = pytest.StashKey[list]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("cosim", "co-simulation regression references (cosim_regression fixture)")
    group.addoption(UPDATE_OPTION, action="store_true", default=False,
                    help="write the reference CSVs of cosim_regression from this run instead of "
                         "comparing with them (the tests pass; the summary lists the files)")
    parser.addini(REFERENCES_INI, default="",
                  help="folder of cosim_regression reference CSVs, relative to the rootdir (default: "
                       "beside each test file, a folder named after it: tests/test_x.py -> tests/test_x/)")


def pytest_configure(config: pytest.Config) -> None:
    config.stash[_WRITTEN] = []


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    written = config.stash.get(_WRITTEN, [])
    if written:
        terminalreporter.write_sep("-", f"cosim: {len(written)} reference(s) written ({UPDATE_OPTION})")
        for nodeid, path, how in written:
            terminalreporter.write_line(f"{how} {path} ({nodeid})")


def _fail(message: str) -> NoReturn:
    """Fail the test with ``message`` alone: no traceback, no chained cosim exception."""
    raise pytest.fail.Exception(message, pytrace=False) from None


def references_dir(request: pytest.FixtureRequest) -> Path:
    """The references folder of the requesting test, absolute: the ``cosim_references`` ini
    folder (relative values are from the rootdir), else ``<test file's folder>/<its stem>``."""
    configured = request.config.getini(REFERENCES_INI)
    if not configured:
        test_file = Path(request.node.path)
        return test_file.parent / test_file.stem
    folder = Path(configured)
    return folder if folder.is_absolute() else request.config.rootpath / folder


class Regression:
    """The callable the `cosim_regression` fixture returns (one per test)."""

    def __init__(self, request: pytest.FixtureRequest, tmp_path: Path, references: Path):
        self.request = request
        self.references = references
        self.tmp_path = tmp_path
        self.update = bool(request.config.getoption(UPDATE_OPTION))
        self.used: set[Path] = set()

    def default_name(self) -> str:
        return re.sub(r"[^A-Za-z0-9_.\-\[\]]", "_", self.request.node.name) + ".csv"

    def __call__(self, scenario: str | Path, *, reference: str | Path | None = None,
                 stop: float | None = None, step: float | None = None,
                 param_sets: Sequence[str | Path] = (), fmu_dirs: Sequence[str | Path] = (),
                 signals: Sequence[str] | None = None,
                 tolerances: Mapping[str, ToleranceSpec] | None = None,
                 rtol: float = 1e-6, atol: float = 1e-9, decimate: int | None = None) -> np.ndarray:
        """Run ``scenario`` and check it against (or with --cosim-update-references, write) the
        reference; returns the run's result (every connector, every step)."""
        from .errors import CosimError
        from .present.metrics import check_tolerance_keys
        from .record.results import select
        from .run.simulation import simulate

        path = self.references / self._reference_name(reference)
        if path in self.used:
            _fail(f"cosim regression: {self.request.node.nodeid} uses the reference {path} twice; pass "
                  "reference=... to give each run its own file.")
        self.used.add(path)
        if decimate is not None and (int(decimate) != decimate or decimate < 1):
            _fail(f"cosim regression: decimate must be a positive integer, not {decimate!r}.")
        candidate_csv = self.tmp_path / f"{path.stem}.candidate.csv"
        where = f"{scenario} (reference {path}; candidate {candidate_csv})"
        try:
            result = simulate(scenario, stop_time=stop, step_size=step, parameter_sets=param_sets,
                              fmu_dirs=fmu_dirs, output=candidate_csv)
            names = [n for n in result.dtype.names if n != "time"]
            chosen = select(names, list(signals)) if signals else names
            check_tolerance_keys(tolerances or {}, chosen)
        except CosimError as e:
            kept = f"; candidate {candidate_csv}" if candidate_csv.exists() else ""   # samples so far, if any
            what = "the candidate run failed" if e.code.run_failed else "the scenario cannot be run"
            _fail(f"cosim regression: {scenario} (reference {path}{kept}): {what} ({e.code.value}): {e}")
        sampled = result[::int(decimate)] if decimate else result
        if self.update:
            self._write(sampled, chosen, path)
        else:
            self._check(sampled, chosen, path, where, tolerances or {}, rtol, atol)
        return result

    def _reference_name(self, reference: str | Path | None) -> str:
        """The reference's file name in the references folder: ``reference`` must be a file name
        (`cosim.safeio.file_name`: no folder, no ``..``), so no test writes outside the folder."""
        from .errors import SetupError
        from .safeio import file_name

        if reference is None:
            return self.default_name()
        try:
            return file_name(str(reference), what="the reference", element="cosim_regression(reference=...)")
        except SetupError as e:
            _fail(f"cosim regression: {self.request.node.nodeid}: {e} Give a file name in the references "
                  f"folder ({self.references}).")

    def _write(self, result: np.ndarray, chosen: list[str], path: Path) -> None:
        from .record.results import write

        how = "rewritten" if path.exists() else "written"
        write(result, path, chosen)
        self.request.config.stash[_WRITTEN].append((self.request.node.nodeid, path, how))

    def _check(self, result: np.ndarray, chosen: list[str], path: Path, where: str,
               tolerances: Mapping[str, ToleranceSpec], rtol: float, atol: float) -> None:
        from .errors import CosimError
        from .present.metrics import compare
        from .record.results import read

        if not path.is_file():
            _fail(f"cosim regression: no reference for {where}. Write it from this run with "
                  f"`pytest {UPDATE_OPTION} '{self.request.node.nodeid}'`, check it and commit it.")
        try:
            stored = read(path)
        except (OSError, CosimError) as e:
            _fail(f"cosim regression: the reference cannot be read: {e} Rewrite it with {UPDATE_OPTION}.")
        stored_names = [n for n in stored.dtype.names if n != "time"]
        missing = [n for n in stored_names if n not in chosen]
        extra = [n for n in chosen if n not in stored_names]
        if missing or extra:
            lines = ([f"  in the reference, not in the run's selected signals: {', '.join(missing)}"] if missing
                     else []) + ([f"  selected in the run, not in the reference: {', '.join(extra)}"] if extra else [])
            _fail(f"cosim regression: the signals differ from the reference for {where}:\n" + "\n".join(lines)
                  + f"\nIf the change is intended, rewrite the reference with {UPDATE_OPTION}.")
        try:
            diffs = compare(stored, result, signals=stored_names, rtol=rtol, atol=atol, tolerances=tolerances)
        except CosimError as e:
            _fail(f"cosim regression: {where}: {e}")
        failed = [d for d in diffs if not d.ok]
        if failed:
            _fail(f"cosim regression: {len(failed)} of {len(diffs)} signals differ from the reference for "
                  f"{where}:\n" + "\n".join(f"  {d.describe()}" for d in failed)
                  + f"\nIf the change is intended, rewrite the reference with {UPDATE_OPTION}.")


@pytest.fixture
def cosim_references_dir(request: pytest.FixtureRequest) -> Path:
    """The folder of the test's reference CSVs (`references_dir`); a conftest may override it."""
    return references_dir(request)


@pytest.fixture
def cosim_regression(request: pytest.FixtureRequest, tmp_path: Path, cosim_references_dir: Path) -> Regression:
    """Run a co-simulation scenario and compare it with a stored reference CSV (see `cosim.pytest_plugin`)."""
    return Regression(request, tmp_path, Path(cosim_references_dir))
