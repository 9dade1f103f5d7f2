"""Pack a validated scenario into a standard SSP archive.

The archive holds ``SystemStructure.ssd`` as written but for one attribute, every
``.ssv``, ``.ssm`` and ``.ssb`` beside it (subfolders included) and each component's FMU at the path its
``source`` names (``resources/<Name>.fmu``), so other SSP tools (libcosim, fmpy.ssp,
OMSimulator) load it as it is.

The attribute: every ``ssd:Component`` without a ``type`` gets
``type="application/x-fmu-sharedlibrary"``, the default SSP 1.0 gives it (all our
components are FMUs); OMSimulator reads only Components that carry it and otherwise
fails with ``KeyError: CRef['setpoint']`` (measured, issue 21).
"""
from __future__ import annotations

import zipfile
from pathlib import Path, PurePosixPath

from lxml import etree

from ..errors import SetupError
from ..safeio import check_member_name, parse_xml
from ..read.ssp import NS, SSD_NAME
from ..model.structure import Plan

#: SSP 1.0 ssd:Component type of an FMU (the default of the attribute)
FMU_TYPE = "application/x-fmu-sharedlibrary"


def typed_ssd(ssd: Path, display: str) -> bytes:
    """The SSD with ``type`` written on every ssd:Component that omits it (see the module docstring)."""
    tree = parse_xml(ssd, display)
    for component in tree.getroot().iterfind(".//ssd:Component", NS):
        if component.get("type") is None:
            component.set("type", FMU_TYPE)
    return etree.tostring(tree, xml_declaration=True, encoding="UTF-8")


def pack(plan: Plan, output: Path) -> Path:
    files = plan.files
    members: dict[str, Path] = {}
    for resource in sorted(r for pattern in ("*.ssv", "*.ssm", "*.ssb") for r in files.base_dir.rglob(pattern)):
        members[resource.relative_to(files.base_dir).as_posix()] = resource
    for name, comp in plan.components.items():
        member = PurePosixPath(comp.source).as_posix()
        if ":" in member.split("/")[0]:
            raise SetupError(f"source '{comp.source}' is a URI, not a path inside the archive; use "
                             "resources/<Name>.fmu.", file=str(files.ssd_file),
                             element=f"ssd:Component '{name}' (line {comp.line})")
        check_member_name(member, output)
        members[member] = plan.fmus[name].path
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_suffix(output.suffix + ".part")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(SSD_NAME, typed_ssd(files.ssd_file, files.display))
        for member, path in members.items():
            z.write(path, member)
    tmp.replace(output)
    return output
