"""SSP files written the way other tools write them (issue 21, item 7): OMSimulator's
``startElement=""`` for a system's own connector and its values for root connectors that feed
nothing, errors found inside an unpacked ``.ssp`` (named ``X.ssp!SystemStructure.ssd``, not the
temporary folder), and a DefaultExperiment with a start time only."""
from __future__ import annotations

import zipfile

import numpy as np
import pytest

import cosim
from cosim.errors import SetupError

HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
        'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
        'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="oms">\n')
EXPERIMENT = ('<ssd:DefaultExperiment startTime="0" stopTime="0.3"><ssd:Annotations>'
              '<ssc:Annotation type="org.greyfmu.simulation"><greyfmu:Simulation '
              'xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" stepSize="0.1"/></ssc:Annotation>'
              '</ssd:Annotations></ssd:DefaultExperiment>')


def _ssd(root_connectors: str, root_values: str, connections: str, experiment: str = EXPERIMENT) -> str:
    """A root system with its own connectors and values, and one Gain (k = 3) 'gain'."""
    values = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" '
              f'name="root"><ssv:Parameters>{root_values}</ssv:Parameters></ssv:ParameterSet>'
              '</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>') if root_values else ""
    connectors = f"<ssd:Connectors>{root_connectors}</ssd:Connectors>" if root_connectors else ""
    wires = f"<ssd:Connections>{connections}</ssd:Connections>" if connections else ""
    return (HEAD + f'<ssd:System name="Root">{connectors}{values}'
            '<ssd:Elements><ssd:Component name="gain" type="application/x-fmu-sharedlibrary" '
            'source="resources/Gain.fmu"><ssd:Connectors>'
            '<ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>'
            '<ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>'
            '<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" '
            'name="g"><ssv:Parameters><ssv:Parameter name="k"><ssv:Real value="3"/></ssv:Parameter>'
            '</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>'
            '</ssd:ParameterBindings></ssd:Component></ssd:Elements>'
            f'{wires}</ssd:System>{experiment}'
            '</ssd:SystemStructureDescription>\n')


def _connector(name: str, kind: str) -> str:
    return f'<ssd:Connector name="{name}" kind="{kind}"><ssc:Real/></ssd:Connector>'


def _value(name: str, value: float) -> str:
    return f'<ssv:Parameter name="{name}"><ssv:Real value="{value}"/></ssv:Parameter>'


def _folder(tmp_path, twin_fmus, text: str):
    folder = tmp_path / "oms"
    (folder / "resources").mkdir(parents=True)
    (folder / "resources" / "Gain.fmu").write_bytes(twin_fmus["Gain"].read_bytes())
    (folder / "SystemStructure.ssd").write_text(text)
    return folder


def _archive(tmp_path, twin_fmus, text: str):
    ssp = tmp_path / "oms.ssp"
    with zipfile.ZipFile(ssp, "w") as z:
        z.writestr("SystemStructure.ssd", text)
        z.write(twin_fmus["Gain"], "resources/Gain.fmu")
    return ssp


def test_empty_start_element_is_the_enclosing_system(tmp_path, twin_fmus):
    """OMSimulator writes startElement="" / endElement="" for the system's own connectors."""
    text = _ssd(_connector("Input", "input") + _connector("Output", "output"), _value("Input", 2.0),
                '<ssd:Connection startElement="" startConnector="Input" endElement="gain" endConnector="u"/>'
                '<ssd:Connection startElement="gain" startConnector="y" endElement="" endConnector="Output"/>')
    res = cosim.simulate(_folder(tmp_path, twin_fmus, text))
    np.testing.assert_array_equal(res["gain.u"], 2.0)
    np.testing.assert_array_equal(res["Output"], 6.0)


def test_a_value_for_a_root_connector_that_feeds_nothing_is_accepted(tmp_path, twin_fmus):
    """OMSimulator's root ssd:Connector Input_cref with a root .ssv value, wired to nothing."""
    text = _ssd(_connector("Input_cref", "input") + _connector("Output", "output"), _value("Input_cref", 5.0),
                '<ssd:Connection startElement="gain" startConnector="y" endElement="" endConnector="Output"/>')
    res = cosim.simulate(_folder(tmp_path, twin_fmus, text))
    np.testing.assert_array_equal(res["Output"], 0.0)        # gain.u keeps its start value 0
    assert "Input_cref" not in res.dtype.names
    # a name that is neither a component's variable nor a system connector is still refused
    text = _ssd(_connector("Input_cref", "input"), _value("Input_crf", 5.0), "")
    with pytest.raises(SetupError, match="'Input_crf' does not start with a component name"):
        cosim.simulate(_folder(tmp_path / "b", twin_fmus, text))


def test_errors_inside_an_ssp_name_the_archive(tmp_path, twin_fmus):
    """Errors found after unpacking name oms.ssp!SystemStructure.ssd, not the deleted temporary folder."""
    text = _ssd("", "", '<ssd:Connection startElement="gain" startConnector="y" endElement="nowhere" '
                'endConnector="u"/>')
    ssp = _archive(tmp_path, twin_fmus, text)
    with pytest.raises(SetupError) as refused:
        cosim.simulate(ssp)
    message = str(refused.value)
    assert f"{ssp}!SystemStructure.ssd" in message and "unknown component 'nowhere'" in message
    assert "cosim-ssp-" not in message
    no_step = _ssd("", "", "", experiment='<ssd:DefaultExperiment startTime="0" stopTime="1"/>')
    (tmp_path / "b").mkdir()
    with pytest.raises(SetupError, match="no step size") as refused:
        cosim.simulate(_archive(tmp_path / "b", twin_fmus, no_step))
    assert "oms.ssp!SystemStructure.ssd" in str(refused.value) and "cosim-ssp-" not in str(refused.value)
