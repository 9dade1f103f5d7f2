"""Write and read SSP 1.0 parameter sets (``.ssv``), and name matrix entries as FMI scalars.

FMI 2.0 has no array variables, so a matrix M is passed as scalars ``M_i_j`` (1-based).
"""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

import numpy as np

SSV_NAMESPACE = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"


def matrix_parameters(name: str, matrix: np.ndarray, skip_zeros: bool = True) -> dict[str, float]:
    """``{"name_i_j": M[i-1, j-1]}``; zeros are skipped by default (the FMUs' start values are 0)."""
    matrix = np.atleast_2d(np.asarray(matrix, dtype=float))
    return {f"{name}_{i + 1}_{j + 1}": float(value) for (i, j), value in np.ndenumerate(matrix)
            if value != 0.0 or not skip_zeros}


def write_parameter_set(path: str | Path, name: str, values: dict[str, float | int], comment: str = "",
                        prefix: str | None = None) -> Path:
    """Write ``values`` (an ``int`` becomes ``ssv:Integer``, everything else ``ssv:Real`` with 17
    significant digits) as the parameter set ``name``; ``prefix`` makes names ``prefix.variable``
    (a system-level set for ``cosim run --param-set``)."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>']
    if comment:
        lines.append(f"<!-- {comment.replace('--', '- -')} -->")
    lines.append(f'<ssv:ParameterSet xmlns:ssv="{SSV_NAMESPACE}" version="1.0" name={quoteattr(name)}>')
    lines.append("  <ssv:Parameters>")
    for variable, value in values.items():
        full = f"{prefix}.{variable}" if prefix else variable
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            element = f'<ssv:Integer value="{int(value)}"/>'
        else:
            element = f'<ssv:Real value="{float(value):.17g}"/>'
        lines.append(f"    <ssv:Parameter name={quoteattr(full)}>{element}</ssv:Parameter>")
    lines.append("  </ssv:Parameters>")
    lines.append("</ssv:ParameterSet>")
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def read_parameter_set(path: str | Path) -> dict[str, float | int]:
    """The ``ssv:Real`` and ``ssv:Integer`` values of a parameter set, by parameter name (the inverse
    of `write_parameter_set`; other types are left out).  Raises ``ValueError`` naming the file and
    the parameter when a value is missing or not a number."""
    path = Path(path)
    values: dict[str, float | int] = {}
    for parameter in ElementTree.parse(path).getroot().iter(f"{{{SSV_NAMESPACE}}}Parameter"):
        name = parameter.get("name", "")
        for kind, convert in (("Real", float), ("Integer", int)):
            element = parameter.find(f"{{{SSV_NAMESPACE}}}{kind}")
            if element is None:
                continue
            try:
                values[name] = convert(element.get("value", ""))
            except ValueError as error:
                raise ValueError(f"{path}: parameter {name!r}: ssv:{kind} value "
                                 f"{element.get('value')!r} is not a number") from error
    return values


def parameter_matrix(values: dict[str, float | int], name: str, rows: int, columns: int) -> np.ndarray:
    """The matrix ``name`` from its scalars ``name_i_j`` (inverse of `matrix_parameters`); an entry
    that is not in ``values`` is 0, as the FMUs' start values are."""
    return np.array([[float(values.get(f"{name}_{i + 1}_{j + 1}", 0.0)) for j in range(columns)]
                     for i in range(rows)])
