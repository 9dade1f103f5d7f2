"""FMU names as a user types them: the grey/gray alias and "did you mean" (build side).

The thesis (000_*) spells its controller "Gray Predictive PI", and the FMU keeps that name:
``GrayPredictivePI`` is its modelIdentifier, so its binary, its GUID and every SSD or
Simulink block that names ``GrayPredictivePI.fmu`` stay valid.  The package and the papers
on grey systems spell it "grey" (``GreyPredictor``, ``greyfmu.grey``), so a name that is
not an FMU but becomes one with Grey and Gray swapped is taken as that FMU: ``greyfmu build
GreyPredictivePI``, ``greyfmu info GreyPredictivePI`` and an SSD naming
``resources/GreyPredictivePI.fmu`` all get ``GrayPredictivePI.fmu``, unchanged.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence

_SPELLINGS = re.compile(r"Gr[ae]y", re.IGNORECASE)


def canonical_name(name: str, available: Sequence[str]) -> str:
    """``name`` if it is one of ``available``, else the one it is with Grey/Gray swapped (the
    alias), else ``name`` unchanged (unknown: the caller says so with `unknown_message`)."""
    if name in available:
        return name
    for candidate in available:
        if _SPELLINGS.sub("Grey", candidate) == _SPELLINGS.sub("Grey", name):
            return candidate
    return name


def aliases(available: Iterable[str]) -> dict[str, str]:
    """The other spelling of each name holding Grey or Gray -> the name (``GreyPredictivePI`` -> ``GrayPredictivePI``)."""
    out = {}
    for name in available:
        other = _SPELLINGS.sub(lambda m: {"grey": "Gray", "gray": "Grey"}[m.group(0).lower()], name)
        if other != name:
            out[other] = name
    return out


def close_names(name: str, available: Iterable[str], n: int = 3) -> list[str]:
    """The names of ``available`` closest to ``name`` (difflib's ratio >= 0.5), case ignored."""
    by_lower = {candidate.lower(): candidate for candidate in available}
    return [by_lower[match] for match in difflib.get_close_matches(name.lower(), list(by_lower), n=n, cutoff=0.5)]


def unknown_message(unknown: Sequence[str], available: Sequence[str]) -> str:
    """``unknown FMU X (did you mean Y?)`` for each name, then where the list of names is."""
    parts = []
    for name in unknown:
        close = close_names(name, available)
        parts.append(f"{name} (did you mean {' or '.join(close)}?)" if close else name)
    fmi2 = [name for name in available if not name.endswith("3") or name[:-1] not in available]
    return (f"unknown FMU {', '.join(parts)}; `greyfmu info` lists the {len(fmi2)} FMUs, each also as FMI 3.0 "
            "<Name>3 (docs/catalogue.md describes each)")


def provided_file_names() -> list[str]:
    """The FMU file names greyfmu's FMU provider makes (entry point ``cosim.fmu_names``): cosim's
    "did you mean" for an FMU file an SSD names and nothing provides (``resources/GreyPredictivPI.fmu``)."""
    from greyfmu.build import FMU_SOURCES, fmi3_fmu_names, fmu_names

    if not FMU_SOURCES.is_dir():
        return []
    names = fmu_names() + fmi3_fmu_names()
    return [f"{name}.fmu" for name in names + list(aliases(names))]
