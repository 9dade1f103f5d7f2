"""The tests of tests/cosim/test_fmucache.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

from cosim.read.fmucache import MARKER, digest


ROOT = Path(__file__).resolve().parents[2]


def _entries(root: Path) -> list[str]:
    """The unpacked FMUs and temporary folders of a cache (not the verdicts of its checks)."""
    return sorted(p.name for p in root.iterdir() if p.name != "verdicts") if root.exists() else []


_RACE = """
import sys, time
from pathlib import Path
from cosim.read.fmucache import unpacked
go = Path(sys.argv[3])
while not go.exists():
    time.sleep(0.001)
print(unpacked(Path(sys.argv[1]), Path(sys.argv[2])))
"""


def test_concurrent_processes_populating_the_cache_make_one_complete_entry(tmp_path, built_fmus):
    fmu, root, go = built_fmus["PID"], tmp_path / "cache", tmp_path / "go"
    procs = [subprocess.Popen([sys.executable, "-c", _RACE, str(fmu), str(root), str(go)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, cwd=ROOT) for _ in range(4)]
    go.touch()
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0] * 4, [err for _, err in outs]
    entry = root / digest(fmu)
    assert {out.strip() for out, _ in outs} == {str(entry / "fmu")}
    assert _entries(root) == [entry.name]    # no temporary folder left behind
    assert (entry / MARKER).is_file()
    with zipfile.ZipFile(fmu) as archive:
        for info in archive.infolist():
            if not info.is_dir():
                assert (entry / "fmu" / info.filename).read_bytes() == archive.read(info), info.filename
