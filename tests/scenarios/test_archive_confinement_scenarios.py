"""The tests of tests/cosim/test_archive_confinement.py that need pythonfmu (issue 29): they run our FMUs
(fmus/, greyfmu build), the scenarios of ssp/ or the pythonfmu FMUs of tests/fmus/."""
from pathlib import Path

import pytest

from cosim.read import ssp
from cosim.errors import SetupError
from cosim.read.resources import locate_fmus
from runhelpers import edited_archive


SSD = Path("ssp/pid_fopdt/SystemStructure.ssd")




@pytest.mark.parametrize("source", ["../../../../etc/passwd", "file:///etc/passwd", "/etc/passwd"])
def test_fmu_source_outside_the_archive_is_refused(tmp_path, source, built_fmus):
    ssv = {"controller.ssv": (SSD.parent / "controller.ssv").read_text()}
    path = edited_archive(tmp_path, SSD, 'source="resources/PID.fmu"', f'source="{source}"', ssv)
    structure = ssp.load(path)
    try:
        with pytest.raises(SetupError) as err:
            locate_fmus(structure)
    finally:
        structure.close()
    text = str(err.value)
    assert "points outside the .ssp archive" in text and str(path) in text and "controller" in text
