"""A connection whose factor and offset (its LinearTransformation and unit conversions) take a
finite value past the largest float (issue 26, item 5): an error naming the connection's source
and target connectors and t, exit 1, the rows before kept, the same from the compiled and the
Python loop, instead of an ``inf`` fed to the target, whose FMU was then blamed."""
from __future__ import annotations

import json

import pytest

from cosim.cli import main
from cosim.errors import RunError
from cosim.kernel import library
from cosim.record.results import read
from cosim.plan.prepare import prepare
from cosim.run.simulation import run
from ssdgen import ssd_text, write_system

#: the C twins of our Step and FirstOrderFilter (tests/twin_fmus.py); the plant only receives u
COMPONENTS = {"step": ("Step.fmu", {"y": "output"}), "plant": ("FirstOrderFilter.fmu", {"u": "input", "y": "output"})}


def _system(tmp_path, twin_fmus, factor: float = 10.0):
    text = ssd_text("overflow", COMPONENTS, [("step", "y", "plant", "u", factor, 0.0)], stop=3.0, step=0.5,
                    parameters={"step": {"t_step": 1.0, "final": 1e308}})
    fmus = {"Step.fmu": twin_fmus["Step"], "FirstOrderFilter.fmu": twin_fmus["FirstOrderFilter"]}
    return write_system(tmp_path / "sys", fmus, text)


KERNELS = ["python"] + (["native"] if library()[0] is not None else [])


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_an_overflowing_connection_fails_naming_it_in_both_loops(tmp_path, twin_fmus, algorithm):
    folder = _system(tmp_path, twin_fmus)
    outcomes = {}
    for kernel in KERNELS:
        out = tmp_path / f"{kernel}.csv"
        prepared = prepare(folder, algorithm=algorithm)
        try:
            with pytest.raises(RunError) as raised:
                run(prepared, output=out, kernel=kernel)
        finally:
            prepared.close()
        meta = json.loads(out.with_suffix(".json").read_text())
        assert meta["kernel"] == kernel and meta["status"] == "failed"
        outcomes[kernel] = (str(raised.value), out.read_text(), meta["last_time"], meta["message"])
    message, rows, last, _ = outcomes["python"]
    # the step's output is 1e308 from t = 1: Jacobi routes it at t = 1, Gauss–Seidel into the
    # plant's step from t = 0.5
    at = 1 if algorithm == "jacobi" else 0.5
    assert "connection step.y -> plant.u" in message and f"overflows to inf at t = {at:g};" in message
    assert "1e+308" in message and "times 10" in message
    assert list(read(tmp_path / "python.csv")["time"]) == [0.0, 0.5]
    assert len(set(outcomes.values())) == 1  # the compiled loop: the same error, rows and metadata


def test_cosim_run_exits_1_naming_the_connection(tmp_path, twin_fmus, capsys):
    folder = _system(tmp_path, twin_fmus)
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "-q", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "discarded" not in err
    assert "connection step.y -> plant.u" in err and "at t = 1" in err
    assert json.loads(out.with_suffix(".json").read_text())["status"] == "failed"


def test_a_factor_that_stays_finite_runs(tmp_path, twin_fmus):
    prepared = prepare(_system(tmp_path, twin_fmus, factor=1.5))
    try:
        result, meta = run(prepared)
    finally:
        prepared.close()
    assert meta["status"] == "completed" and result["plant.u"][-1] == 1.5e308
