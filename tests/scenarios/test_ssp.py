"""Reading SSP 1.0 files: step-size annotations, parameter precedence, archive and bare .ssd forms."""
from __future__ import annotations

import shutil
import zipfile

import pytest

import cosim
from cosim.read import ssp
from cosim.errors import SetupError

SCENARIO = "ssp/pid_fopdt"
OSP = ('<ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm><osp:FixedStepAlgorithm '
       'baseStepSize="0.25"/></osp:Algorithm></ssc:Annotation>')
OMS = ('<ssc:Annotation type="org.openmodelica"><oms:Annotations xmlns:oms="https://raw.githubusercontent.com/'
       'OpenModelica/OMSimulator/master/schema/oms.xsd"><oms:SimulationInformation><oms:FixedStepMaster '
       'description="oms-ma" stepSize="0.5"/></oms:SimulationInformation></oms:Annotations></ssc:Annotation>')


@pytest.fixture
def scenario(tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(SCENARIO, folder)
    return folder


def _set_annotations(folder, *annotations):
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    start = text.index("<ssd:Annotations>")
    end = text.index("</ssd:Annotations>") + len("</ssd:Annotations>")
    body = "".join(annotations)
    ssd.write_text(text[:start] + (f"<ssd:Annotations>{body}</ssd:Annotations>" if body else "") + text[end:])


def test_step_size_precedence(scenario):
    assert ssp.load(scenario).step_size_source == "annotation org.greyfmu.simulation"
    _set_annotations(scenario, OMS, OSP)
    s = ssp.load(scenario)
    assert (s.step_size, s.step_size_source) == (0.25, "annotation com.opensimulationplatform")
    _set_annotations(scenario, OMS)
    s = ssp.load(scenario)
    assert (s.step_size, s.step_size_source) == (0.5, "annotation org.openmodelica")
    prepared = cosim.prepare(scenario, step_size=0.05)
    assert (prepared.grid.step, prepared.step_source) == (0.05, "command line")
    prepared.close()
    _set_annotations(scenario)
    assert ssp.load(scenario).step_size is None


def test_bare_ssd_and_archive_read_the_same(scenario, tmp_path):
    bare = ssp.load(scenario / "SystemStructure.ssd")
    archive = tmp_path / "a.ssp"
    with zipfile.ZipFile(archive, "w") as z:
        for f in scenario.iterdir():
            z.write(f, f.name)
    packed = ssp.load(archive)
    try:
        assert packed.archive == archive and packed.ssd_file != bare.ssd_file
        assert list(packed.components) == list(bare.components) == ["setpoint", "load", "controller", "plant"]
        assert [(p.name, p.value) for p in packed.components["controller"].parameters] == \
               [(p.name, p.value) for p in bare.components["controller"].parameters]
    finally:
        packed.close()
    assert not packed.base_dir.exists()


def test_parameter_precedence_component_system_command_line(scenario, tmp_path):
    """Component bindings < system bindings < --param-set (SSP 1.0 ParameterBindings)."""
    ssd = scenario / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace(
        "<ssd:Elements>", '<ssd:ParameterBindings><ssd:ParameterBinding prefix="controller." '
                          'source="sys.ssv"/></ssd:ParameterBindings><ssd:Elements>'))
    (scenario / "sys.ssv").write_text(
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" '
        'name="sys"><ssv:Parameters><ssv:Parameter name="Kc"><ssv:Real value="4"/></ssv:Parameter>'
        '<ssv:Parameter name="Ti"><ssv:Real value="9"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    cli = tmp_path / "cli.ssv"
    cli.write_text(
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" '
        'name="cli"><ssv:Parameters><ssv:Parameter name="controller.Ti"><ssv:Real value="11"/></ssv:Parameter>'
        '</ssv:Parameters></ssv:ParameterSet>')
    prepared = cosim.prepare(scenario, parameter_sets=[cli])
    values = {f"{s.component}.{s.variable.name}": s.value for s in prepared.plan.start_values}
    prepared.close()
    assert values["controller.Kc"] == 4.0      # system level beat controller.ssv's 8.0345
    assert values["controller.Ti"] == 11.0     # the command line beat both
    assert values["controller.Td"] == 1.5363   # only the component level gave it


def test_system_parameter_without_a_component_prefix(scenario, tmp_path):
    bad = tmp_path / "bad.ssv"
    bad.write_text(
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" '
        'name="b"><ssv:Parameters><ssv:Parameter name="controler.Kc"><ssv:Real value="1"/></ssv:Parameter>'
        '</ssv:Parameters></ssv:ParameterSet>')
    with pytest.raises(SetupError) as err:
        cosim.prepare(scenario, parameter_sets=[bad])
    assert "bad.ssv" in str(err.value) and "'controller'" in str(err.value)


def test_schema_violation_names_the_line(scenario):
    ssd = scenario / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('kind="input"', 'kind="in"', 1))
    with pytest.raises(SetupError) as err:
        ssp.load(scenario)
    assert "SSP 1.0 schema" in str(err.value) and "line 52" in str(err.value) and "'in'" in str(err.value)


def test_folder_without_ssd_lists_what_it_has(tmp_path):
    (tmp_path / "other.ssd").write_text("<x/>")
    with pytest.raises(SetupError) as err:
        ssp.load(tmp_path)
    assert "no SystemStructure.ssd" in str(err.value) and "other.ssd" in str(err.value)
