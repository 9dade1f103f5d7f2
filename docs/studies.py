"""Support for the docs' long studies: parameter sets written from values, and the measured runs kept as they
finish so that a long report resumes where it stopped (issue 46).

The reports that run a claim over seeds and over the values a paper leaves open (docs/btg_spacing_report.py,
docs/osmm_settings_report.py) take hours on one core.  Each run's figures of merit are appended, one JSON line
per run, to ``build/studies/<study>.jsonl`` under a key that names everything the run depends on (scenario
files, parameter values, stop time, step); a report started again reads the file and runs only what is missing.
A line is written only after its run completed, so an interrupted study loses at most the run in progress.
Delete the file to measure again (after a change of the FMUs or of the merits' definition: bump ``version``).
``GREYFMU_STUDIES`` names another folder for the files: a study run from a copy of the tree (so that editing the
tree, which rebuilds the FMUs, cannot change a run half way) can write where the tree's report reads.
``GREYFMU_STUDY_SHARD=k/N`` makes a process measure only the runs whose key hashes to k modulo N (the others answer
NaN and are not written): N such processes share a study, and a last one without the variable writes the tables
from the file.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

ROOT = Path(__file__).resolve().parents[1]
FOLDER = Path(os.environ.get("GREYFMU_STUDIES", ROOT / "build" / "studies"))


class NotMeasured(dict):
    """The merits of a run another shard measures: NaN for every figure."""

    def __missing__(self, key: str) -> float:
        return math.nan


class StudyCache:
    """Figures of merit per run key, read from and appended to ``build/studies/<name>.jsonl``."""

    def __init__(self, name: str, version: int = 1) -> None:
        self.path = FOLDER / f"{name}.jsonl"
        self.version = version
        self.measure_missing = True
        """False: a run not in the file answers NotMeasured (tables from what has been measured)."""
        self.done: dict[str, dict] = {}
        if self.path.exists():
            for line in self.path.read_text().splitlines():
                if line.strip():
                    entry = json.loads(line)
                    if entry.get("version") == version:
                        self.done[entry["key"]] = entry["merits"]

    @staticmethod
    def _mine(key: str) -> bool:
        shard = os.environ.get("GREYFMU_STUDY_SHARD")
        if not shard:
            return True
        k, n = (int(part) for part in shard.split("/"))
        return int(hashlib.sha1(key.encode()).hexdigest(), 16) % n == k

    @staticmethod
    def key(description: Mapping) -> str:
        """A run's key: its description as canonical JSON."""
        return json.dumps(description, sort_keys=True)

    def get(self, description: Mapping, measure: Callable[[], dict]) -> dict:
        """The merits of the run `description`: from the file, or measured now and appended to it."""
        key = self.key(description)
        if key not in self.done and not (self.measure_missing and self._mine(key)):
            return NotMeasured()
        if key not in self.done:
            merits = measure()
            FOLDER.mkdir(parents=True, exist_ok=True)
            with self.path.open("a") as file:
                file.write(json.dumps({"version": self.version, "key": key, "merits": merits}) + "\n")
            self.done[key] = merits
        return self.done[key]


def parameter_set(values: Mapping[str, int | float], path: Path) -> Path:
    """Write `values` (component.variable -> value; an int is an SSV Integer, a float a Real) as an SSP 1.0
    parameter set at `path` and return the path."""
    rows = "\n".join(f'    <ssv:Parameter name={quoteattr(name)}><ssv:{"Integer" if isinstance(v, int) else "Real"} '
                     f'value="{v!r}"/></ssv:Parameter>' for name, v in values.items())
    path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/'
                    'SSP1/SystemStructureParameterValues" version="1.0" name="study">\n  <ssv:Parameters>\n'
                    f"{rows}\n  </ssv:Parameters>\n</ssv:ParameterSet>\n")
    return path
