"""An .ssp archive may refer only to its own members (cosim.read.ssp.resolve_uri): an archive
from elsewhere must not make the master read files outside it."""
from pathlib import Path

import pytest

from cosim.read import ssp
from cosim.errors import SetupError
from cosim.read.resources import locate_fmus
from runhelpers import edited_archive

SSD = Path("ssp/pid_fopdt/SystemStructure.ssd")




def test_parameter_set_outside_the_archive_is_refused(tmp_path):
    outside = tmp_path / "secret.ssv"
    outside.write_text("not for the archive")
    path = edited_archive(tmp_path, SSD, 'source="controller.ssv"', 'source="../secret.ssv"')
    with pytest.raises(SetupError) as err:
        ssp.load(path)
    assert "points outside the .ssp archive" in str(err.value) and "ParameterBinding" in str(err.value)


def test_file_uri_with_a_host_is_refused(tmp_path):
    with pytest.raises(SetupError, match="with a host"):
        ssp.resolve_uri("file://server/share/x.ssv", tmp_path)


def test_a_folder_scenario_may_still_refer_outside_its_folder(tmp_path):
    assert ssp.resolve_uri("../common/x.ssv", tmp_path) == tmp_path / "../common/x.ssv"


def test_a_megabyte_long_value_does_not_make_a_megabyte_message(tmp_path):
    ssv = {"controller.ssv": (SSD.parent / "controller.ssv").read_text()}
    path = edited_archive(tmp_path, SSD, 'source="resources/Step.fmu"', f'source="{"x" * 1_000_000}.fmu"', ssv)
    structure = ssp.load(path)
    try:
        with pytest.raises(SetupError) as err:
            locate_fmus(structure, use_providers=False)
    finally:
        structure.close()
    text = str(err.value)
    assert len(text) < 4100 and "characters cut" in text and text.startswith(str(path))


# --------------------------------------------------------------------------- on our FMUs (pythonfmu)


@pytest.mark.pythonfmu
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
