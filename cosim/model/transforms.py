"""What happens to a value on its way from an output to an input (or a root output connector, or a
parameter): one value type per kind of transformation.

* `Affine`: ``y = factor·x + offset``: an ``ssc:LinearTransformation`` (SSP 1.0
  SystemStructureCommon.xsd), a unit conversion (`cosim.model.units.conversion`, SSP 1.0 §5.3.4),
  and their compositions along a path through system connectors;
* `Table`: a value looked up in a table of source → target values: the
  ``ssc:BooleanMappingTransformation``, ``ssc:IntegerMappingTransformation`` and
  ``ssc:EnumerationMappingTransformation`` of a connection (GTransformationChoice) once resolved
  to exchanged values (Booleans as 0 and 1, Enumerations by item value; `MappingTable` is the
  table as read), and the tables of an ``.ssm`` mapping entry; a value the table does not name
  has no target (`Unmapped`);
* `Chain`: transformations of different kinds applied one after the other.

Every kind offers the same operations, and the master uses nothing else of them: `apply` (one
value), `apply_array` (NumPy, per chunk of recorded rows; NaN where a table names no target),
`then` (composition: this, then that; `compose` folds many), `inverse` where it exists, `text`
(the one rendering, of the messages, ``cosim info`` and the run metadata), `as_json` and
`from_json` (a run journal's header), `native` (its C form, which the compiled loop runs:
`cosim.kernel`; None: the operation stays with Python) and `resolve` (a transformation as read
from an SSD, checked against the variables at the ends of its connection, in the form that acts
on exchanged values).  A new kind is one class here (and the reader of its element,
`cosim.read.ssp`): the plan, parameters, input tables, root outputs, metadata, plots and both
interpreters take it as they take these.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import SetupError
from .fmu import Variable, exchange_type
from .frozen import FrozenMap

#: a connection's end as messages name it and its variable: ("plant.y", Variable)
End = tuple[str, Variable]
#: the range of a C int: what the compiled loop's tables hold
_C_INT = (-2**31, 2**31 - 1)


@runtime_checkable
class Transform(Protocol):
    """A transformation of values (see the module docstring)."""

    @property
    def identity(self) -> bool:
        """Whether it leaves every value as it is."""
        ...

    @property
    def partial(self) -> bool:
        """Whether some values have no image (a `Table` names no target for them)."""
        ...

    def apply(self, value):
        """The image of one value (a `Table` raises `Unmapped` for a value it does not name)."""
        ...

    def apply_array(self, values: np.ndarray) -> np.ndarray:
        """The images of an array of values, as floats; NaN where a table names no target."""
        ...

    def then(self, after: Transform) -> Transform:
        """This transformation, then ``after``."""
        ...

    def inverse(self) -> Transform | None:
        """The transformation that undoes this one, or None where none does."""
        ...

    def text(self, x: str = "x") -> str:
        """The image of ``x`` as text (``2*x + 0.5``, ``map(x; 1→2, 2→1)``)."""
        ...

    def as_json(self) -> dict:
        """As JSON data (`from_json` reads it back)."""
        ...

    def native(self) -> tuple | None:
        """Its C form for the compiled loop (`cosim.kernel.NativeOp`), or None: Python makes it."""
        ...

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Transform:
        """The transformation acting on exchanged values between ``source`` and ``target`` (None: a
        root-system output connector), refused (`SetupError`) where it does not apply."""
        ...


@runtime_checkable
class Transformation(Protocol):
    """A transformation as an SSD gives it on a connection (an `Affine` LinearTransformation, a
    `MappingTable`): `resolve` checks it against the ends and makes it the `Transform` of the
    exchanged values."""

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Transform:
        """The `Transform` of the exchanged values from ``source`` to ``target`` (None: a root-system
        output connector), refused (`SetupError`) where the transformation does not apply."""
        ...


class Unmapped(ValueError):
    """A value a `Table` names no target for."""

    def __init__(self, table: Table, value):
        super().__init__(f"{table.shown(value)} is not a source value of {table.element}")
        self.table, self.value = table, value


def _number(value: float) -> str:
    """A float as its shortest text that reads back to the same bits (``2``, ``0.001``, ``1e-05``)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


@dataclass(frozen=True)
class Affine:
    """``y = factor·x + offset`` (two roundings: the product, then the sum)."""
    factor: float = 1.0
    offset: float = 0.0

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.offset == 0.0

    partial = False

    def apply(self, value):
        return value * self.factor + self.offset

    def apply_array(self, values: np.ndarray) -> np.ndarray:
        return values * self.factor + self.offset

    def then(self, after: Transform) -> Transform:
        if isinstance(after, Affine):
            return Affine(after.factor * self.factor, after.factor * self.offset + after.offset)
        return chain(self, after)

    def inverse(self) -> Affine | None:
        return Affine(1.0 / self.factor, -self.offset / self.factor) if self.factor != 0.0 else None

    def text(self, x: str = "x") -> str:
        scaled = x if self.factor == 1.0 else f"{_number(self.factor)}*{x}"
        if self.offset == 0.0:
            return scaled
        return f"{scaled} {'-' if self.offset < 0 else '+'} {_number(abs(self.offset))}"

    def as_json(self) -> dict:
        return {"affine": [self.factor, self.offset]}

    def native(self) -> tuple:
        return ("affine", self.factor, self.offset)

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Affine:
        """A LinearTransformation acts on Real values only (SSP 1.0 SystemStructureCommon.xsd)."""
        if exchange_type(source[1]) != "Real":
            raise SetupError(f"a LinearTransformation applies to Real connections only; {source[0]} is "
                             f"{source[1].type}.", file=file, element=where)
        return self


IDENTITY = Affine()


@dataclass(frozen=True)
class Table:
    """A table of source → target values; ``boolean``: its values are Booleans, any value but 0
    looked up as 1; ``element``: where it comes from, for messages (``ssc:IntegerMappingTransformation
    (line 12)``, several joined by commas when composed)."""
    mapping: FrozenMap
    boolean: bool = False
    element: str = "a mapping table"

    @property
    def identity(self) -> bool:
        return False

    partial = True

    def key(self, value):
        return int(value != 0) if self.boolean else value

    def apply(self, value):
        key = self.key(value)
        if key not in self.mapping:
            raise Unmapped(self, key)
        return self.mapping[key]

    def apply_array(self, values: np.ndarray) -> np.ndarray:
        keys = (values != 0).astype(np.int64) if self.boolean else values
        out = np.full(np.shape(values), np.nan)
        for source, target in self.mapping.items():
            out[keys == source] = target
        return out

    def then(self, after: Transform) -> Transform:
        if isinstance(after, Table):
            return Table(FrozenMap((k, after.mapping[v]) for k, v in self.mapping.items() if v in after.mapping),
                         self.boolean, f"{self.element}, {after.element}")
        return chain(self, after)

    def inverse(self) -> Table | None:
        targets = list(self.mapping.values())
        if len(set(targets)) != len(targets):
            return None
        return Table(FrozenMap((v, k) for k, v in self.mapping.items()), self.boolean, f"the inverse of {self.element}")

    def shown(self, value) -> str:
        """A value as the SSP files write it: ``true``/``false``, a number, an item name in quotes."""
        if self.boolean or isinstance(value, bool):
            return "true" if value else "false"
        return f"'{value}'" if isinstance(value, str) else str(value)

    def text(self, x: str = "x") -> str:
        return f"map({x}; " + ", ".join(f"{self.shown(k)}→{self.shown(v)}" for k, v in self.mapping.items()) + ")"

    def as_json(self) -> dict:
        return {"table": [[k, v] for k, v in self.mapping.items()], "boolean": self.boolean, "element": self.element}

    def native(self) -> tuple | None:
        """Sorted keys and their values, as C ints; None when one is no C int."""
        items = sorted(self.mapping.items())
        if not all(isinstance(v, int) and _C_INT[0] <= v <= _C_INT[1] for kv in items for v in kv):
            return None
        return ("table", tuple(k for k, _ in items), tuple(v for _, v in items), self.boolean)

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Table:
        return self


@dataclass(frozen=True)
class Chain:
    """Transformations of different kinds, applied in order."""
    parts: tuple[Transform, ...]

    @property
    def identity(self) -> bool:
        return all(p.identity for p in self.parts)

    @property
    def partial(self) -> bool:
        return any(p.partial for p in self.parts)

    def apply(self, value):
        for part in self.parts:
            value = part.apply(value)
        return value

    def apply_array(self, values: np.ndarray) -> np.ndarray:
        for part in self.parts:
            values = part.apply_array(values)
        return values

    def then(self, after: Transform) -> Transform:
        return chain(self, after)

    def inverse(self) -> Chain | None:
        inverses = [p.inverse() for p in reversed(self.parts)]
        return None if any(i is None for i in inverses) else Chain(tuple(inverses))

    def text(self, x: str = "x") -> str:
        for part in self.parts:
            x = part.text(x)
        return x

    def as_json(self) -> dict:
        return {"chain": [p.as_json() for p in self.parts]}

    def native(self) -> None:
        return None

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Chain:
        return Chain(tuple(p.resolve(source, target, file, where) for p in self.parts))


def chain(first: Transform, after: Transform) -> Transform:
    """``first`` then ``after`` as few parts as they make: an identity `Affine` left out, neighbours
    of the closed kinds merged (`Affine` with `Affine`, `Table` with `Table`), one part alone."""
    parts: list[Transform] = []
    for part in (*(first.parts if isinstance(first, Chain) else (first,)),
                 *(after.parts if isinstance(after, Chain) else (after,))):
        if isinstance(part, Affine) and part.identity:
            continue
        if parts and isinstance(part, (Affine, Table)) and type(parts[-1]) is type(part):
            parts[-1] = parts[-1].then(part)
        else:
            parts.append(part)
    if not parts:
        return IDENTITY
    return parts[0] if len(parts) == 1 else Chain(tuple(parts))


def compose(transforms: Iterable[Transform]) -> Transform:
    """The transformations one after the other (the identity for none)."""
    result: Transform = IDENTITY
    for t in transforms:
        result = result.then(t)
    return result


def from_json(data: Mapping) -> Transform:
    """A transformation from its `as_json` form."""
    if "affine" in data:
        factor, offset = data["affine"]
        return Affine(float(factor), float(offset))
    if "table" in data:
        return Table(FrozenMap((k, v) for k, v in data["table"]), bool(data["boolean"]), data["element"])
    return Chain(tuple(from_json(part) for part in data["chain"]))


# --------------------------------------------------------------------------- as read from an SSD

#: the exchange type (`cosim.model.fmu.exchange_type`) each mapping transformation applies to
APPLIES_TO = {"Boolean": "Boolean", "Integer": "Integer", "Enumeration": "Integer"}


@dataclass(frozen=True)
class MappingTable:
    """The ``ssc:BooleanMappingTransformation``, ``ssc:IntegerMappingTransformation`` or
    ``ssc:EnumerationMappingTransformation`` of an ``ssd:Connection`` as read: its ``ssc:MapEntry``
    source → target values, booleans, integers or item names.  `resolve` makes it the `Table` of
    the exchanged values: the schema makes each valid for its type, the Boolean table for Boolean
    connections, the Integer table for Integer and Enumeration ones (on the item values), the
    Enumeration table for Enumeration ones, by item name, a source name looked up among the items
    of the source variable's type, a target name among those of the target's (FMI 2.0 §2.2.3)."""
    kind: str
    entries: tuple[tuple[bool | int | str, bool | int | str], ...]
    line: int

    @property
    def element(self) -> str:
        return f"ssc:{self.kind}MappingTransformation (line {self.line})"

    def resolve(self, source: End, target: End | None, file: str, where: str) -> Table:
        (src, sv) = source
        element = f"{where}, {self.element}"
        if exchange_type(sv) != APPLIES_TO[self.kind]:
            valid = {"Boolean": "Boolean", "Integer": "Integer and Enumeration", "Enumeration": "Enumeration"}[self.kind]
            route = src if target is None else f"{src} -> {target[0]}"
            raise SetupError(f"ssc:{self.kind}MappingTransformation applies to {valid} connections; {route} is "
                             f"{sv.type}.", file=file, element=element)
        boolean = exchange_type(sv) == "Boolean"
        if self.kind == "Boolean":
            return Table(FrozenMap((int(s), int(t)) for s, t in self.entries), boolean, self.element)
        if self.kind == "Integer":
            return Table(FrozenMap(self.entries), boolean, self.element)
        if target is None:
            raise SetupError(f"ssc:EnumerationMappingTransformation maps item names to those of its target's type; "
                             f"a root-system output connector has none ({src} feeds it).", file=file, element=element)
        source_items, target_items = _items(source, file, element), _items(target, file, element)
        out = {}
        for s, t in self.entries:
            for name, items, (label, var) in ((s, source_items, source), (t, target_items, target)):
                if name not in items:
                    raise SetupError(f"ssc:MapEntry '{s}' -> '{t}': '{name}' is not an item of {label}'s type "
                                     f"{var.declared_type.name} (items: {', '.join(items)}).", file=file,
                                     element=element)
            out[source_items[s]] = target_items[t]
        return Table(FrozenMap(out), boolean, self.element)


def _items(end: End, file: str, element: str) -> dict[str, int]:
    label, var = end
    items = dict(var.declared_type.items if var.declared_type else ())
    if var.type != "Enumeration" or not items:
        raise SetupError(f"ssc:EnumerationMappingTransformation maps item names; {label} is {var.type} "
                         "without enumeration items.", file=file, element=element)
    return items
