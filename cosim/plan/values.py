"""Values given as text on the command line typed by the FMU variables they are for: a
``--start-value NAME=VALUE`` (`cosim.plan.prepare.start_value`) and a sweep's ``--set`` items and
seeds (`cosim.sweep.values`)."""
from __future__ import annotations

import math
import re

import numpy as np

from ..errors import SetupError

Value = float | int | bool | str
_RANGE = re.compile(r"^\s*([-+0-9.eE]+)\s*:\s*([-+0-9.eE]+)\s*:\s*(\d+)\s*$")
#: the range of an FMI 2.0 Integer (fmi2Integer is a C int)
INTEGER_RANGE = (-2**31, 2**31 - 1)
#: the most runs one sweep may plan (a typo such as --seeds 1..1000000000 is refused, not allocated),
#: so the most values a range item may give
MAX_RUNS = 1_000_000


def typed_values(raw: Value, var_type: str, name: str, element: str = "--set") -> list[Value]:
    """A --set item (or a seed, ``element="--seeds"``) as values of the FMU variable's type; a range
    item gives several."""
    where = {"element": element, "variable": name}
    if isinstance(raw, str) and var_type in ("Real", "Integer") and (m := _RANGE.match(raw)):
        start, stop, count = float(m[1]), float(m[2]), int(m[3])
        if not (math.isfinite(start) and math.isfinite(stop)) or not 1 <= count <= MAX_RUNS:
            raise SetupError(f"the range {raw} needs finite ends and a count from 1 to {MAX_RUNS}.", **where)
        points = np.linspace(start, stop, count)
        if var_type == "Integer":
            if not all(float(p).is_integer() for p in points):
                raise SetupError(f"the range {raw} does not fall on integers; {name} is an Integer.", **where)
            return [int(p) for p in points]
        return [float(p) for p in points]
    try:
        if var_type == "Real" and not isinstance(raw, bool):
            if not math.isfinite(number := float(raw)):
                raise SetupError(f"'{raw}' is not a finite number; {name} is a Real.", **where)
            return [number]
        if var_type == "Integer" and not isinstance(raw, bool):
            return [_integer(raw, where)]
        elif var_type == "Boolean":
            if isinstance(raw, bool):
                return [raw]
            if str(raw).lower() in ("true", "1", "false", "0"):
                return [str(raw).lower() in ("true", "1")]
        elif var_type == "String":
            return [str(raw)]
    except ValueError:
        pass
    raise SetupError(f"'{raw}' is not a {var_type} value, which the FMU declares for this variable.", **where)


def _integer(raw: Value, where: dict[str, str]) -> int:
    """An Integer item (``12``, ``1e3``) inside the FMI 2.0 Integer range."""
    try:
        number = raw if isinstance(raw, int) else int(str(raw).strip())
    except ValueError:
        as_float = float(raw)
        if not as_float.is_integer():
            raise
        number = int(as_float)
    lo, hi = INTEGER_RANGE
    if not lo <= number <= hi:
        raise SetupError(f"{number} is outside the range of an FMI 2.0 Integer [{lo}, {hi}].", **where)
    return number
