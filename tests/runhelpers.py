"""Helpers the master's tests share, folded from the files split between tests/cosim and
tests/scenarios (issue 29): a CLI call's exit status and message, a run by kernel with its
samples, metadata and error, samples compared bit for bit, an .ssp archive of an edited SSD."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from cosim.cli import main
from cosim.errors import RunError
from cosim.plan.prepare import prepare
from cosim.run.simulation import run


def cli_exit(capsys, code: int, *argv: str) -> str:
    """`cosim` with ``argv``: it exits with ``code`` and no traceback (a refusal, exit 2, with
    one ``cosim: error:`` line); its standard error."""
    got = main(list(argv))
    err = capsys.readouterr().err
    assert got == code, err
    assert "Traceback" not in err
    if code == 2:
        assert err.count("cosim: error:") == 1, err
    return err


def refused(capsys, *argv: str) -> str:
    """`cli_exit` with exit status 2."""
    return cli_exit(capsys, 2, *argv)


def run_kernel(folder: Path, kernel: str, results: Path | None = None, **kw) -> tuple[np.ndarray | None, dict, str]:
    """One run of ``folder`` with ``kernel``: the samples, the metadata (of the result file's
    JSON, in ``results``, by default beside the system's folder) and the error, if any."""
    out = (results or folder.parent) / f"{kernel}.csv"
    prepared = prepare(folder, algorithm=kw.pop("algorithm", None))
    try:
        result, meta = run(prepared, output=out, kernel=kernel, **kw)
        return result, meta, ""
    except RunError as e:
        return e.result, json.loads(out.with_suffix(".json").read_text()), str(e)
    finally:
        prepared.close()


def assert_same(a: np.ndarray, b: np.ndarray) -> None:
    """The same signals and samples, bit for bit (NaN equal to NaN)."""
    assert a.dtype.names == b.dtype.names and len(a) == len(b)
    for name in a.dtype.names:
        assert np.array_equal(a[name], b[name], equal_nan=True), name


def edited_archive(tmp_path: Path, ssd: Path, old: str, new: str, extra: dict[str, str] | None = None) -> Path:
    """``tmp_path/x.ssp`` holding ``ssd`` with its first ``old`` replaced by ``new``, and the
    ``extra`` members (name -> text)."""
    text = ssd.read_text()
    assert old in text
    path = tmp_path / "x.ssp"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("SystemStructure.ssd", text.replace(old, new, 1))
        for name, content in (extra or {}).items():
            z.writestr(name, content)
    return path
