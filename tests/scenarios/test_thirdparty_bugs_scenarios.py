"""The tests of tests/cosim/test_thirdparty_bugs.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from __future__ import annotations

import numpy as np
import pytest

import cosim
from cosim.errors import SetupError
from ssdgen import ssd_text, write_system
from testfmus import build_test_fmus, build_test_fmus3, edited_copy


@pytest.fixture(scope="module")
def pyfmus(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pyfmus")
    return {**build_test_fmus(tmp / "fmi2"), **build_test_fmus3(tmp / "fmi3")}


def test_string_parameter_on_fmi2(tmp_path, pyfmus):
    """A String binding reaches an FMI 2.0 FMU (Labels: length = len(text))."""
    comps = {"lab": ("Labels.fmu", {"text": "input", "length": "output"})}
    folder = write_system(tmp_path / "s", {"Labels.fmu": pyfmus["Labels"]},
                          ssd_text("str", comps, [], stop=0.2, step=0.1, parameters={"lab": {"text": "abcde"}}))
    res = cosim.simulate(folder)
    np.testing.assert_array_equal(res["lab.length"], 5)


def test_scheduled_execution_only_fmi3_is_refused_as_such(tmp_path, pyfmus):
    """An FMI 3.0 FMU with only <ScheduledExecution>: the refusal names that interface."""
    se = edited_copy(pyfmus["Echo3"], tmp_path / "SE.fmu",
                     lambda text: text.replace("<CoSimulation", "<ScheduledExecution"))
    comps = {"e": ("SE.fmu", {})}
    folder = write_system(tmp_path / "s", {"SE.fmu": se}, ssd_text("se", comps, [], stop=0.2, step=0.1))
    with pytest.raises(SetupError, match="only a Scheduled Execution interface") as refused:
        cosim.simulate(folder)
    assert "Model Exchange" not in str(refused.value).split("only a Scheduled")[0]
