"""The DigitalPI FMU's parameters from a design: numbered scalars ``Gp_i_j`` … in a ``.ssv`` file.

FMI 2.0 has neither arrays nor (in our slave base) String parameters, so the design travels as
numbered Real parameters of fixed maximum size; `write_design_ssv` writes the active blocks and
`stored_design` reads them back: a deployed controller runs the gains of its parameter set, not a
design recomputed on the machine that runs it (the Wood–Berry design at the paper's disc moves by
up to 2.7 % between OpenBLAS kernels, docs/digital_pi.md "How sensitive the design is").
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from greyfmu.control.digital_pi.design import DigitalPIDesign
from greyfmu.control.digital_pi.errors import DesignError
from greyfmu.ssv import matrix_parameters, parameter_matrix, read_parameter_set, write_parameter_set

MAX_ORDER = 24
"""Largest augmented plant order n + D·m the DigitalPI FMU accepts."""
MAX_CHANNELS = 3
"""Largest number of inputs (= outputs) of the DigitalPI FMU."""


def design_parameters(design: DigitalPIDesign) -> dict[str, float | int]:
    """FMU parameters of a design: Ts, na, m (Integers) and every entry of Gp, Hp, Gammap, Cp, F, K1,
    K2, Hc (zeros too: the FMU's start values are another design's)."""
    a = design.augmented
    na, m = a.Hp.shape
    if na > MAX_ORDER or m > MAX_CHANNELS:
        raise DesignError(f"the DigitalPI FMU takes at most order {MAX_ORDER} and {MAX_CHANNELS} channels, "
                          f"the design has order {na} and {m} channels")
    values: dict[str, float | int] = {"Ts": float(design.Ts), "na": int(na), "m": int(m)}
    matrices = {"Gp": a.Gp, "Hp": a.Hp, "Gammap": a.Gammap, "Cp": a.Cp, "F": design.F, "K1": design.K1,
                "K2": design.K2, "Hc": design.Hc}
    for name, matrix in matrices.items():
        values.update(matrix_parameters(name, matrix, skip_zeros=False))
    return values


def write_design_ssv(design: DigitalPIDesign, path: str | Path, component: str | None = None,
                     comment: str = "") -> Path:
    """Write the design as a parameter set for the DigitalPI FMU; with ``component`` the names are
    ``component.variable`` (a system-level set), else plain (a component's ParameterBinding)."""
    note = comment or (f"Digital PI design (Zhou et al. 2006): T = {design.Ts}, alpha = {design.alpha}, "
                       f"beta = {design.beta}; written by greyfmu.control.digital_pi.write_design_ssv")
    return write_parameter_set(path, component or "controller", design_parameters(design), note, component)


def stored_design(design: DigitalPIDesign, path: str | Path) -> DigitalPIDesign:
    """``design`` with the matrices the DigitalPI FMU runs (Gp, Hp, Gammap, Cp, F, K1, K2, Hc) taken
    from the parameter set ``path`` written by `write_design_ssv` — what `closed_loop` needs to
    predict the co-simulation.  Refused (`DesignError`, naming the file) when the set's order or
    channel count is not the design's."""
    values = read_parameter_set(path)
    a = design.augmented
    na, m = a.Hp.shape
    p = a.Cp.shape[0]
    if (values.get("na"), values.get("m")) != (na, m):
        raise DesignError(f"{path}: the parameter set has na = {values.get('na')}, m = {values.get('m')}; "
                          f"the design has na = {na}, m = {m}")

    def matrix(name: str, rows: int, columns: int) -> np.ndarray:
        return parameter_matrix(values, name, rows, columns)

    augmented = replace(a, Gp=matrix("Gp", na, na), Hp=matrix("Hp", na, m), Gammap=matrix("Gammap", na, p),
                        Cp=matrix("Cp", p, na))
    return replace(design, augmented=augmented, F=matrix("F", m, na), K1=matrix("K1", m, p),
                   K2=matrix("K2", m, p), Hc=matrix("Hc", p, p))
