"""pytest plugin (``pytest11`` entry point): regression fixtures for co-simulation scenarios.

Installing the ``greyfmu`` distribution registers this plugin with pytest; no conftest.py
is needed.  A test runs a scenario and checks it against a stored reference CSV with the
comparison engine `cosim.regression` (the same as ``cosim compare``), and against control-loop
metric targets::

    def test_pid_loop(cosim_regression):
        result = cosim_regression("ssp/pid_fopdt", stop=60.0,
                                  signals=["plant.y", "controller.u"],
                                  tolerances={"controller.*": {"rtol": 1e-5, "atol": 1e-8, "time": 0.1}},
                                  metrics={"plant.y": {"overshoot": (20, 2)}})
        # ``result`` is the run's structured array (every connector), for further checks

The first run fails: the reference does not exist yet.  Write it (and rewrite it after an
intended change) with ``pytest --cosim-update-references``; those tests pass and the
terminal summary lists the files written and, for each one rewritten, what changed (signals
added, removed, and out of tolerance with their largest difference).  Commit the references.

``cosim_regression(scenario, *, reference=None, stop=None, step=None, param_sets=(),
fmu_dirs=(), signals=None, tolerances=None, rtol=1e-6, atol=1e-9, time=0.0, mode="tube",
decimate=None, metrics=None)``

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
- ``signals``: globs selecting the compared (and stored) signals, default every connector;
  ``[]`` compares no samples (metric targets alone, no reference file).
- ``tolerances``: ``{glob: (rtol, atol), (rtol, atol, time) or {"rtol": .., "atol": .., "time": ..}}``;
  the most specific key matching a signal wins (`cosim.regression.tolerances.tolerance_for`),
  others get ``rtol``/``atol``/``time``.  A point passes when |run − reference| <=
  max(atol, rtol·|reference|) with the reference taken anywhere within ±time s (the tube of
  `cosim.regression.tube`); the run is checked at the reference's time points.
- ``mode``: "tube", "csv-compare" or "fmi-cross-check" (`cosim.regression.engine`).
- ``decimate``: keep every n-th sample (first included) in the reference and the comparison,
  to keep long references small.
- ``metrics``: ``{signal: {metric: (expected, tolerance), ...}}`` (`cosim.regression.targets`:
  IAE, ISE, ITAE, overshoot, rise_time, settling_time, peak_error; optional "setpoint",
  "event", "band").

The test fails when a reference signal is not produced (or a selected one is not in the
reference), when a signal leaves its tube or a metric misses its target: the message lists
each failing signal with its first and worst violation (time, value, reference, tube bounds)
and each missed metric, then the path of the difference report (an HTML page in the test's
``tmp_path``, interactive and offline, with a PNG beside it; `cosim.regression.report`), the
reference's path and the run's own CSV.  Each signal's and metric's verdict is a property of
the test (``record_property``), so JUnit XML (``--junitxml``) carries them.  A run error or an
invalid scenario fails the test with cosim's message.

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

    from .regression.tolerances import ToleranceSpec

UPDATE_OPTION = "--cosim-update-references"
REFERENCES_INI = "cosim_references"

#: (node id, reference path, what changed (`changes`)), listed in the terminal summary
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
        for nodeid, path, what in written:
            terminalreporter.write_line(f"{'written' if what == 'new' else 'rewritten'} {path} ({nodeid}): {what}")


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
                 rtol: float = 1e-6, atol: float = 1e-9, time: float = 0.0, mode: str = "tube",
                 decimate: int | None = None, metrics: Mapping[str, Mapping] | None = None) -> np.ndarray:
        """Run ``scenario`` and check it against (or with --cosim-update-references, write) the
        reference, and its ``metrics`` targets; returns the run's result (every connector, every step)."""
        from .errors import CosimError
        from .regression.tolerances import check_tolerance_keys
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
            chosen = names if signals is None else select(names, list(signals)) if signals else []
            check_tolerance_keys(tolerances or {}, chosen)
            targets = self._metrics(result, metrics or {}, candidate_csv)
        except CosimError as e:
            kept = f"; candidate {candidate_csv}" if candidate_csv.exists() else ""   # samples so far, if any
            what = "the candidate run failed" if e.code.run_failed else "the scenario cannot be run"
            _fail(f"cosim regression: {scenario} (reference {path}{kept}): {what} ({e.code.value}): {e}")
        sampled = result[::int(decimate)] if decimate else result
        rule = dict(tolerances=tolerances or {}, rtol=rtol, atol=atol, time=time, mode=mode)
        if self.update and chosen:
            self._write(sampled, chosen, path, rule)
            verdicts = []
        else:
            verdicts = self._check(sampled, chosen, path, where, rule) if chosen else []
        self._conclude(verdicts, targets, path, where)
        return result

    def _metrics(self, result: np.ndarray, metrics: Mapping[str, Mapping], candidate_csv: Path) -> list:
        """The metric targets' verdicts (`cosim.regression.targets`), the loops read from the run's metadata."""
        from .regression.targets import check_metrics
        from .present.report import read_metadata

        return check_metrics(result, metrics, read_metadata(candidate_csv)) if metrics else []

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

    def _write(self, result: np.ndarray, chosen: list[str], path: Path, rule: Mapping) -> None:
        """Write the reference, and note what changed against the one it replaces (`changes`)."""
        from .record.results import write

        before = changes(path, result, chosen, rule)
        write(result, path, chosen)
        self.request.config.stash[_WRITTEN].append((self.request.node.nodeid, path, before))

    def _check(self, result: np.ndarray, chosen: list[str], path: Path, where: str, rule: Mapping) -> list:
        from .errors import CosimError
        from .regression.engine import compare
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
            return compare(stored, result, signals=stored_names, **rule)
        except CosimError as e:
            _fail(f"cosim regression: {where}: {e}")

    def _conclude(self, verdicts: list, targets: list, path: Path, where: str) -> None:
        """Record each verdict as a JUnit XML property; on a failure, write the difference report
        (HTML and PNG in the test's tmp_path) and fail naming each failing signal and metric."""
        from .regression.report import write_report

        for v in verdicts:
            self.request.node.user_properties.append((f"cosim {v.signal}", v.describe()))
        for m in targets:
            self.request.node.user_properties.append((f"cosim {m.signal} {m.metric}", m.describe()))
        failed = [v for v in verdicts if not v.passed]
        missed = [m for m in targets if not m.passed]
        if not failed and not missed:
            return
        page, png = write_report(verdicts, self.tmp_path / f"{path.stem}.diff.html", metrics=targets,
                                 title=f"{self.request.node.nodeid}: {where}")
        lines = [f"  {v.describe()}" for v in failed] + [f"  {m.describe()}" for m in missed]
        counts = ([f"{len(failed)} of {len(verdicts)} signals differ from the reference"] if failed else []) + \
            ([f"{len(missed)} of {len(targets)} metric targets missed"] if missed else [])
        _fail(f"cosim regression: {' and '.join(counts)} for {where}:\n" + "\n".join(lines)
              + f"\ndifference report: {page}" + (f" (plot {png})" if png.exists() else "")
              + (f"\nIf the change is intended, rewrite the reference with {UPDATE_OPTION}." if failed else ""))


def changes(path: Path, result: np.ndarray, chosen: list[str], rule: Mapping) -> str:
    """What writing ``result`` over the reference ``path`` changes, in one line: "new", or the
    signals added, removed and out of tolerance (each with its largest |new − old|), or "no
    signal out of tolerance"."""
    from .errors import CosimError
    from .regression.engine import compare
    from .record.results import matches, read

    if not path.is_file():
        return "new"
    try:
        old = read(path)
    except (OSError, CosimError) as e:
        return f"the old one could not be read ({e})"
    names = [n for n in old.dtype.names if n != "time"]
    parts = [f"{label}: {', '.join(group)}" for label, group in
             (("added", [n for n in chosen if n not in names]), ("removed", [n for n in names if n not in chosen]))
             if group]
    kept = [n for n in names if n in chosen]
    tolerances = {k: v for k, v in rule["tolerances"].items() if any(matches(n, k) for n in kept)}
    try:
        verdicts = compare(old, result, signals=kept, **{**rule, "tolerances": tolerances})
    except CosimError as e:
        return "; ".join(parts + [str(e)])
    changed = [f"{v.signal} (worst |new − old| {v.max_abs:.3g}" + (f" at t = {v.worst.time:.6g} s)" if v.worst else ")")
               for v in verdicts if not v.passed]
    parts.append(f"changed: {', '.join(changed)}" if changed else "no signal out of tolerance")
    return "; ".join(parts)


@pytest.fixture
def cosim_references_dir(request: pytest.FixtureRequest) -> Path:
    """The folder of the test's reference CSVs (`references_dir`); a conftest may override it."""
    return references_dir(request)


@pytest.fixture
def cosim_regression(request: pytest.FixtureRequest, tmp_path: Path, cosim_references_dir: Path) -> Regression:
    """Run a co-simulation scenario and compare it with a stored reference CSV (see `cosim.pytest_plugin`)."""
    return Regression(request, tmp_path, Path(cosim_references_dir))
