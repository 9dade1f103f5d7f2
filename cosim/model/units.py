"""Physical units: definitions, where they come from, and the affine maps between them.

A unit is what FMI 2.0 §2.2.2 (``UnitDefinitions/Unit/BaseUnit``) and SSP 1.0
(SystemStructureCommon.xsd, ``TUnit``/``BaseUnit``) define: the exponents of the
SI base units kg, m, s, A, K, mol, cd and of rad, plus a factor and an offset
such that

    value_in_base_units = factor · value + offset

(degC is ``K=1, offset=273.15``; % is dimensionless with ``factor=0.01``).  Two
units with the same exponents have the same dimension and convert into each
other by an affine map dst = a·src + b (`cosim.model.transforms.Affine`); units of different dimensions never do.

Where a unit name is looked up (`UnitScope`): the definitions of the file that
uses the name first (an FMU's ``UnitDefinitions`` for its variables, the SSD's
``ssd:Units`` for its connectors, an ``.ssv``'s ``ssv:Units`` for its values),
then the SSD and the FMU concerned (`SystemUnits`), then the small `BUILTIN`
table of common process units — so a scenario may name ``degC`` or ``kgf/cm2``
without defining them.  An SSD and an FMU that define the same name differently
are refused.  How connections, SSD connectors and parameter values use this:
`cosim.plan.routing` (``hops_map``, ``connector_unit``) and `cosim.plan.parameters` (``_convert_value``).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from ..errors import SetupError
from .fmu import UnitDefinition
from .frozen import FrozenMap
from .transforms import Affine

#: Base-unit attribute names in FMI 2.0 / SSP 1.0 order.
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@dataclass(frozen=True)
class Unit:
    """A unit definition: value_in_base_units = factor·value + offset."""
    name: str
    #: exponents of kg, m, s, A, K, mol, cd, rad (`BASE_UNITS`)
    exponents: tuple[int, ...]
    factor: float = 1.0
    offset: float = 0.0
    #: the file that defines it ("built-in" for `BUILTIN`)
    source: str = "built-in"

    @property
    def dimension(self) -> str:
        """The base-unit exponents as text, e.g. ``kg·m^-1·s^-2``; ``1`` when dimensionless."""
        parts = [b if e == 1 else f"{b}^{e}" for b, e in zip(BASE_UNITS, self.exponents) if e]
        return "·".join(parts) or "1"

    def same_as(self, other: Unit) -> bool:
        """Same dimension, factor and offset (the name and the defining file may differ)."""
        return (self.exponents == other.exponents
                and math.isclose(self.factor, other.factor, rel_tol=1e-12)
                and math.isclose(self.offset, other.offset, rel_tol=1e-12, abs_tol=1e-12))

    def describe(self) -> str:
        """The definition as a reader checks it: ``'kgf/cm2' = 98066.5·kg·m^-1·s^-2``."""
        text = f"'{self.name}' = {self.factor:g}·{self.dimension}"
        return text + (f" {'+' if self.offset >= 0 else '-'} {abs(self.offset):g}" if self.offset else "")


def make_unit(name: str, source: str = "built-in", factor: float = 1.0, offset: float = 0.0,
              **exponents: int) -> Unit:
    """A `Unit` from keyword exponents (``kg=1, m=-1, s=-2``), as a BaseUnit element writes them."""
    unknown = set(exponents) - set(BASE_UNITS)
    if unknown:
        raise ValueError(f"unknown base units {sorted(unknown)}")
    return Unit(name, tuple(int(exponents.get(b, 0)) for b in BASE_UNITS), float(factor), float(offset), source)


def _builtin() -> dict[str, Unit]:
    """Common process units.  Factors: SI Brochure, 9th ed. (BIPM 2019) for SI prefixes and the
    non-SI units accepted for use with the SI (Table 8: min, h, t); NIST SP 811 (2008) Appendix B
    for the others."""
    pressure = {"kg": 1, "m": -1, "s": -2}
    power = {"kg": 1, "m": 2, "s": -3}
    table = [
        make_unit("1"),                                   # dimensionless (SI Brochure §2.3.3)
        make_unit("%", factor=0.01),                      # 1 % = 0.01 (SI Brochure §5.4.7)
        make_unit("K", K=1),                              # SI base unit
        make_unit("degC", K=1, offset=273.15),            # T/K = t/°C + 273.15 (SI Brochure §2.3.1)
        make_unit("degF", K=1, factor=5 / 9, offset=459.67 * 5 / 9),  # T/K = (t/°F + 459.67)/1.8 (NIST SP 811 B.9)
        make_unit("Pa", **pressure),                      # SI derived unit, N/m²
        make_unit("kPa", factor=1e3, **pressure),         # SI prefix kilo
        make_unit("MPa", factor=1e6, **pressure),         # SI prefix mega
        make_unit("bar", factor=1e5, **pressure),         # 1 bar = 1E+05 Pa (NIST SP 811 B.8)
        make_unit("kgf/cm2", factor=98066.5, **pressure),  # 1 kgf/cm² = 9.806 65E+04 Pa (NIST SP 811 B.8)
        make_unit("s", s=1),                              # SI base unit
        make_unit("min", factor=60.0, s=1),               # 1 min = 60 s (SI Brochure Table 8)
        make_unit("h", factor=3600.0, s=1),               # 1 h = 3600 s (SI Brochure Table 8)
        make_unit("m", m=1),                              # SI base unit
        make_unit("mm", factor=1e-3, m=1),                # SI prefix milli
        make_unit("kg", kg=1),                            # SI base unit
        make_unit("kg/s", kg=1, s=-1),
        make_unit("t/h", factor=1000 / 3600, kg=1, s=-1),  # 1 t = 1000 kg (SI Brochure Table 8), 1 h = 3600 s
        make_unit("W", **power),                          # SI derived unit, J/s
        make_unit("kW", factor=1e3, **power),
        make_unit("MW", factor=1e6, **power),
        make_unit("N", kg=1, m=1, s=-2),                  # SI derived unit
        make_unit("m3/s", m=3, s=-1),
        make_unit("rad", rad=1),                          # SI derived unit (FMI counts it as a base unit)
    ]
    units = {u.name: u for u in table}
    for alias, name in (("kgf/cm²", "kgf/cm2"), ("°C", "degC"), ("°F", "degF"), ("m³/s", "m3/s")):
        units[alias] = Unit(alias, units[name].exponents, units[name].factor, units[name].offset)
    return units


#: Used for a name that neither the FMU nor the SSP files define.
BUILTIN: dict[str, Unit] = _builtin()


def fmu_units(unit_definitions: Iterable[UnitDefinition], source: str) -> dict[str, Unit]:
    """The units of an FMU's ``UnitDefinitions`` (`cosim.model.fmu.FMUDescription.unit_definitions`);
    a Unit without a BaseUnit is dimensionless with factor 1 (FMI 2.0 §2.2.2)."""
    units = {}
    for u in unit_definitions:
        if u.base is None:
            units[u.name] = make_unit(u.name, source)
        else:
            units[u.name] = Unit(u.name, u.base, u.factor, u.offset, source)
        check_definition(units[u.name], file=source, element=f"UnitDefinitions/Unit '{u.name}'")
    return units


def check_definition(unit: Unit, **where) -> None:
    """Refuse a factor of zero (every value would be 0 in base units, and nothing converts back)
    and a factor or offset that is not finite."""
    if unit.factor == 0.0 or not (math.isfinite(unit.factor) and math.isfinite(unit.offset)):
        raise SetupError(f"unit '{unit.name}' has factor {unit.factor:g} and offset {unit.offset:g}; the "
                         "factor must be a finite non-zero number and the offset finite.", **where)


def check_agree(first: Mapping[str, Unit], second: Mapping[str, Unit], **where) -> None:
    """Refuse a unit name the two tables define differently, naming both definitions and files."""
    for name in first.keys() & second.keys():
        a, b = first[name], second[name]
        if not a.same_as(b):
            raise SetupError(f"unit '{name}' is defined differently in {a.source} ({a.describe()}) and in "
                             f"{b.source} ({b.describe()}).", **where,
                             hint="Give the unit one definition, or use another name for one of them.")


class UnitScope:
    """The unit tables visible from one place, searched in order, then `BUILTIN`."""

    def __init__(self, *tables: Mapping[str, Unit]):
        self.tables = [t for t in tables if t] + [BUILTIN]

    def resolve(self, name: str, **where) -> Unit:
        for table in self.tables:
            if name in table:
                return table[name]
        sources = sorted({u.source for t in self.tables[:-1] for u in t.values()})
        raise SetupError(f"unit '{name}' is not defined" + (f" in {', '.join(sources)}" if sources else "")
                         + " and is not a built-in unit.", **where,
                         hint="Define it in the SSD's ssd:Units (ssc:Unit with an ssc:BaseUnit).")


    def find(self, name: str) -> Unit | None:
        return next((table[name] for table in self.tables if name in table), None)


@dataclass(frozen=True)
class SystemUnits:
    """The unit tables of one system: the SSD's ``ssd:Units`` and each component's FMU
    ``UnitDefinitions``.  Built once per plan (`of`), which refuses an SSD unit that an FMU defines
    differently (SSP 1.0 gives no precedence between them, so either choice would be a guess)."""
    ssd: Mapping[str, Unit]
    fmu: Mapping[str, Mapping[str, Unit]]

    @classmethod
    def of(cls, ssd_units: Mapping[str, Unit], fmu_tables: Mapping[str, Mapping[str, Unit]], file: str) -> SystemUnits:
        for comp, table in fmu_tables.items():
            check_agree(ssd_units, table, file=file, element=f"ssd:Units and the FMU of component '{comp}'")
        return cls(FrozenMap(ssd_units), FrozenMap((comp, FrozenMap(t)) for comp, t in fmu_tables.items()))

    def for_variable(self, comp: str) -> UnitScope:
        """Where the unit of an FMU variable is looked up: its FMU, the SSD, built-ins."""
        return UnitScope(self.fmu[comp], self.ssd)

    def for_connector(self, comp: str) -> UnitScope:
        """Where an SSD connector's ``ssc:Real unit`` is looked up: the SSD, the FMU, built-ins."""
        return UnitScope(self.ssd, self.fmu[comp])

    def for_value(self, comp: str, local: Mapping[str, Unit], **where) -> UnitScope:
        """Where a parameter value's unit is looked up: its parameter set's ``ssv:Units``, the SSD,
        the FMU that receives it, built-ins; the parameter set must agree with the SSD."""
        check_agree(local, self.ssd, **where)
        return UnitScope(local, self.ssd, self.fmu[comp])


def conversion(src: Unit, dst: Unit, context: str = "", **where) -> Affine:
    """The `cosim.model.transforms.Affine` a·x + b taking a value in ``src`` to ``dst``; refuses
    different dimensions, naming both units and their dimensions (``context`` says what is
    converted)."""
    if src.exponents != dst.exponents:
        raise SetupError(f"{context}cannot convert '{src.name}' ({src.dimension}) to '{dst.name}' "
                         f"({dst.dimension}): the dimensions differ.", **where)
    return Affine(src.factor / dst.factor, (src.offset - dst.offset) / dst.factor)
