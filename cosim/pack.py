"""Pack a validated scenario into a standard SSP archive.

The archive holds ``SystemStructure.ssd`` as written, every ``.ssv`` beside it
(subfolders included) and each component's FMU at the path its ``source``
names (``resources/<Name>.fmu``), so other SSP tools (libcosim, fmpy.ssp,
OMSimulator) load it as it is.
"""
from __future__ import annotations

import zipfile
from pathlib import Path, PurePosixPath

from .errors import SetupError
from .safeio import check_member_name
from .ssp import SSD_NAME
from .structure import Plan


def pack(plan: Plan, output: Path) -> Path:
    files = plan.files
    members: dict[str, Path] = {SSD_NAME: files.ssd_file}
    for ssv in sorted(files.base_dir.rglob("*.ssv")):
        members[ssv.relative_to(files.base_dir).as_posix()] = ssv
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
        for member, path in members.items():
            z.write(path, member)
    tmp.replace(output)
    return output
