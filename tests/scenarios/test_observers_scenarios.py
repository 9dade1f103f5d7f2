"""The tests of tests/cosim/test_observers.py that need pythonfmu (issue 29): a run of the
pythonfmu FMU Failing (tests/fmus/Failing.py) and our FirstOrderFilter."""
from __future__ import annotations

import json

import pyarrow.parquet as pq
import pytest
from pythonfmu.builder import FmuBuilder

from cosim.cli import main
from cosim.record.results import read
from ssdgen import ssd_text, write_system
from testfmus import HERE as TEST_FMU_SOURCES


@pytest.fixture(scope="module")
def failing_fmu(tmp_path_factory):
    return FmuBuilder.build_FMU(TEST_FMU_SOURCES / "Failing.py", dest=tmp_path_factory.mktemp("failing"),
                                needsExecutionTool="false")


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_run_failing_half_way_leaves_its_rows_readable(tmp_path, built_fmus, failing_fmu, suffix, capsys):
    """Failing.fmu refuses the step from t = 5 s (fmi2Fatal); 5001 rows, more than one 4096-row chunk."""
    components = {"f": ("Failing.fmu", {"u": "input", "y": "output"}),
                  "lag": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}
    text = ssd_text("failing", components, [("f", "y", "lag", "u")], stop=10.0, step=0.001,
                    parameters={"f": {"fail_time": 5.0}})
    folder = write_system(tmp_path / "sys", {"Failing.fmu": failing_fmu,
                                             "FirstOrderFilter.fmu": built_fmus["FirstOrderFilter"]}, text)
    output = tmp_path / f"out{suffix}"
    assert main(["run", str(folder), "-q", "-o", str(output)]) == 1
    assert "fmi2DoStep returned Fatal at t = 5" in capsys.readouterr().err
    if suffix == ".csv":
        result = read(output)
        time, y = result["time"], result["f.y"]
    else:
        parquet = pq.ParquetFile(output)
        assert parquet.metadata.num_row_groups == 2
        table = parquet.read()
        time, y = table.column("time").to_numpy(), table.column("f.y").to_numpy()
        assert json.loads(pq.read_metadata(output).metadata[b"cosim"])["status"] == "failed"
    assert len(time) == 5001 and time[-1] == pytest.approx(5.0) and y[-1] == pytest.approx(5.0)
    assert json.loads(output.with_suffix(".json").read_text())["status"] == "failed"
