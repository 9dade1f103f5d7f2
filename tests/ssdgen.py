"""Write small, real SSP 1.0 system structures for master tests.

`write_system` lays out a scenario folder (SystemStructure.ssd plus
resources/*.fmu copied in) from a compact description; tests that need a broken
file start from its text and change one thing.
"""
from __future__ import annotations

import shutil
from pathlib import Path

HEADER = ('<?xml version="1.0" encoding="UTF-8"?>\n'
          '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"\n'
          '  xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"\n'
          '  xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
          ' version="1.0" name="{name}">\n')
TYPE_OF = {float: "Real", int: "Integer", bool: "Boolean", str: "String"}


def ssd_text(name: str, components: dict, connections: list, *, stop: float = 1.0, step: float | None = 0.01,
             parameters: dict | None = None) -> str:
    """components: name -> (fmu file name, {connector: kind}); connections: (a, ca, b, cb[, factor, offset]);
    parameters: component -> {variable: value} as inline ParameterBindings."""
    parameters = parameters or {}
    out = [HEADER.format(name=name), '  <ssd:System name="root">\n    <ssd:Elements>\n']
    for comp, (fmu, connectors) in components.items():
        out.append(f'      <ssd:Component name="{comp}" source="resources/{fmu}">\n')
        if connectors:
            out.append('        <ssd:Connectors>\n')
            for conn, kind in connectors.items():
                out.append(f'          <ssd:Connector name="{conn}" kind="{kind}"/>\n')
            out.append('        </ssd:Connectors>\n')
        if comp in parameters:
            out.append('        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>\n'
                       '          <ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>\n')
            for var, value in parameters[comp].items():
                kind = TYPE_OF[type(value)]
                text = str(value).lower() if isinstance(value, bool) else value if isinstance(value, str) \
                    else repr(value)
                out.append(f'            <ssv:Parameter name="{var}"><ssv:{kind} value="{text}"/></ssv:Parameter>\n')
            out.append('          </ssv:Parameters></ssv:ParameterSet>\n'
                       '        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>\n')
        out.append('      </ssd:Component>\n')
    out.append('    </ssd:Elements>\n')
    if connections:
        out.append('    <ssd:Connections>\n')
    for c in connections:
        a, ca, b, cb = c[:4]
        if len(c) > 4:
            out.append(f'      <ssd:Connection startElement="{a}" startConnector="{ca}" endElement="{b}" '
                       f'endConnector="{cb}"><ssc:LinearTransformation factor="{c[4]}" offset="{c[5]}"/>'
                       '</ssd:Connection>\n')
        else:
            out.append(f'      <ssd:Connection startElement="{a}" startConnector="{ca}" endElement="{b}" '
                       f'endConnector="{cb}"/>\n')
    if connections:
        out.append('    </ssd:Connections>\n')
    out.append('  </ssd:System>\n')
    out.append(f'  <ssd:DefaultExperiment startTime="0" stopTime="{stop}">\n')
    if step is not None:
        out.append('    <ssd:Annotations><ssc:Annotation type="org.greyfmu.simulation">'
                   f'<greyfmu:Simulation xmlns:greyfmu="urn:greyfmu:ssp:simulation:1.0" stepSize="{step}"/>'
                   '</ssc:Annotation></ssd:Annotations>\n')
    out.append('  </ssd:DefaultExperiment>\n</ssd:SystemStructureDescription>\n')
    return "".join(out)


def write_system(folder: Path, fmus: dict[str, Path], text: str) -> Path:
    """Create ``folder`` with SystemStructure.ssd = text and resources/<file> for each FMU."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "resources").mkdir(exist_ok=True)
    for file_name, path in fmus.items():
        shutil.copy(path, folder / "resources" / file_name)
    (folder / "SystemStructure.ssd").write_text(text)
    return folder
