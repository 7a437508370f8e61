"""Physical quantities written with units, converted to SI once at load time.

Procedures write quantities as ``20 mm``, ``180 deg``, ``3 N`` or
``2000 N*s/m``. A small table of the units procedures use converts them to SI
(metres, kilograms, seconds, radians) without importing pint, which alone
costs ~0.3 s to import and would break the start-up budget of
``suture validate``. Any unit outside the table is handed to pint, imported
lazily, whose result is converted to the same SI form. The tests check the
table against pint.

Dimensions are exponent tuples over (length, mass, time, angle). Angles are
their own dimension so that ``180 deg`` given for a length is caught.

Parameter models mark the unit of a float field with :class:`Unit`, for
example ``Length = Annotated[float, Unit("m")]``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Annotated, Any

from suture_engine.errors import SutureError

__all__ = [
    "Acceleration",
    "Angle",
    "AngularSpeed",
    "Damping",
    "Dimension",
    "Duration",
    "Force",
    "Length",
    "LinearDensity",
    "Mass",
    "Position",
    "Quantity",
    "Rate",
    "Speed",
    "Stiffness",
    "Unit",
    "UnitError",
    "dimension_name",
    "parse_quantity",
    "parse_unit",
]

Dimension = tuple[int, int, int, int]
"""Exponents of (length, mass, time, angle)."""

_DIMLESS: Dimension = (0, 0, 0, 0)
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_PATTERN = rf"^\s*{_NUMBER}\s*[A-Za-zµ°%].*$"
_NUMBER_ONLY = re.compile(rf"^\s*{_NUMBER}\s*$")
_QUANTITY_RE = re.compile(rf"^\s*({_NUMBER})\s*(.*?)\s*$")
_FACTOR_RE = re.compile(r"([A-Za-zµ°%]+)(?:(?:\^|\*\*)([-+]?\d+))?")


class UnitError(SutureError):
    """A unit that cannot be parsed, or a quantity of the wrong dimension.

    Attributes:
        text: the offending text.
        expected: the expected dimension (human form), or "".
        found: the found dimension (human form), or "".
    """

    code = "unit-mismatch"

    def __init__(self, message: str, text: str = "", expected: str = "", found: str = "") -> None:
        super().__init__(message)
        self.text = text
        self.expected = expected
        self.found = found


# name -> (factor to SI, dimension)
_UNITS: dict[str, tuple[float, Dimension]] = {
    "m": (1.0, (1, 0, 0, 0)),
    "meter": (1.0, (1, 0, 0, 0)),
    "km": (1e3, (1, 0, 0, 0)),
    "cm": (1e-2, (1, 0, 0, 0)),
    "mm": (1e-3, (1, 0, 0, 0)),
    "um": (1e-6, (1, 0, 0, 0)),
    "µm": (1e-6, (1, 0, 0, 0)),
    "kg": (1.0, (0, 1, 0, 0)),
    "g": (1e-3, (0, 1, 0, 0)),
    "s": (1.0, (0, 0, 1, 0)),
    "ms": (1e-3, (0, 0, 1, 0)),
    "us": (1e-6, (0, 0, 1, 0)),
    "min": (60.0, (0, 0, 1, 0)),
    "Hz": (1.0, (0, 0, -1, 0)),
    "kHz": (1e3, (0, 0, -1, 0)),
    "rad": (1.0, (0, 0, 0, 1)),
    "deg": (math.pi / 180.0, (0, 0, 0, 1)),
    "degree": (math.pi / 180.0, (0, 0, 0, 1)),
    "N": (1.0, (1, 1, -2, 0)),
    "mN": (1e-3, (1, 1, -2, 0)),
    "kN": (1e3, (1, 1, -2, 0)),
    "kgf": (9.80665, (1, 1, -2, 0)),
    "Pa": (1.0, (-1, 1, -2, 0)),
    "kPa": (1e3, (-1, 1, -2, 0)),
    "J": (1.0, (2, 1, -2, 0)),
    "W": (1.0, (2, 1, -3, 0)),
}


def dimension_name(dim: Dimension) -> str:
    """A readable form of a dimension, e.g. ``length/time``; ``dimensionless``."""
    names = ("length", "mass", "time", "angle")
    num = [n if e == 1 else f"{n}^{e}" for n, e in zip(names, dim, strict=True) if e > 0]
    den = [n if e == -1 else f"{n}^{-e}" for n, e in zip(names, dim, strict=True) if e < 0]
    if not num and not den:
        return "dimensionless"
    return ("*".join(num) or "1") + ("/" + "/".join(den) if den else "")


@lru_cache(maxsize=256)
def parse_unit(text: str) -> tuple[float, Dimension]:
    """Parse a unit expression such as ``N*s/m`` or ``mm/s^2``.

    Args:
        text: the unit expression; factors joined by ``*`` or ``/``, each with
            an optional integer power (``^2`` or ``**2``).

    Returns:
        (factor to SI, dimension).

    Raises:
        UnitError: the unit is unknown (neither in the table nor known to pint).
    """
    text = text.strip()
    if not text:
        return 1.0, _DIMLESS
    factor, dim = 1.0, [0, 0, 0, 0]
    pos, sign = 0, 1
    compact = text.replace(" ", "")
    if compact.startswith("1/") and len(compact) > 2:  # "1/s"
        pos, sign = 2, -1
    while pos < len(compact):
        match = _FACTOR_RE.match(compact, pos)
        if match is None or match.group(1) not in _UNITS:
            return _parse_with_pint(text)
        f, d = _UNITS[match.group(1)]
        power = int(match.group(2) or 1) * sign
        factor *= f**power
        for i in range(4):
            dim[i] += d[i] * power
        pos = match.end()
        if pos < len(compact):
            if compact.startswith("**", pos) or compact[pos] not in "*/":
                return _parse_with_pint(text)
            sign = 1 if compact[pos] == "*" else -1
            pos += 1
            if pos == len(compact):
                return _parse_with_pint(text)
    return factor, (dim[0], dim[1], dim[2], dim[3])


@lru_cache(maxsize=1)
def _registry() -> Any:
    import pint  # lazy: ~0.3 s to import

    return pint.UnitRegistry(cache_folder=None)


def _parse_with_pint(text: str) -> tuple[float, Dimension]:
    try:
        ureg = _registry()
        q = ureg.Quantity(1.0, text)
        base = q.to_base_units()
        dims = base.dimensionality
        extra = set(dims) - {"[length]", "[mass]", "[time]"}
        if extra:
            raise UnitError(f"unit {text!r} has an unsupported dimension", text=text)
        dim: Dimension = (
            int(dims.get("[length]", 0)),
            int(dims.get("[mass]", 0)),
            int(dims.get("[time]", 0)),
            0,
        )
        value = float(base.magnitude)
        # pint treats radian as dimensionless; keep angles distinct.
        if str(base.units) in ("radian", "dimensionless") and q.check("[]"):
            if "rad" in text or "deg" in text or "°" in text or "turn" in text:
                dim = (0, 0, 0, 1)
                value = float(q.to("radian").magnitude)
        return value, dim
    except UnitError:
        raise
    except Exception as exc:  # pint raises many kinds; all mean "not a unit we know"
        raise UnitError(f"unknown unit {text!r}", text=text) from exc


@dataclass(frozen=True)
class Quantity:
    """A value in SI with its dimension.

    Attributes:
        value: magnitude in SI units (m, kg, s, rad and their products).
        dim: exponents of (length, mass, time, angle).
    """

    value: float
    dim: Dimension

    def __str__(self) -> str:
        return f"{self.value:g} [{dimension_name(self.dim)}]"


def parse_quantity(text: str) -> Quantity:
    """Parse ``"20 mm"`` into ``Quantity(0.02, length)``.

    Raises:
        UnitError: the text is not a number followed by a known unit.
    """
    match = _QUANTITY_RE.match(text)
    if match is None:
        raise UnitError(f"expected a quantity such as '20 mm', found {text!r}", text=text)
    factor, dim = parse_unit(match.group(2))
    value = float(match.group(1)) * factor
    if not math.isfinite(value):
        raise UnitError(f"expected a finite quantity, found {text!r}", text=text)
    return Quantity(value, dim)


@dataclass(frozen=True)
class Unit:
    """Marks a float field (or a sequence of floats) with its SI unit.

    Attributes:
        unit: the SI unit the field is stored in, e.g. ``"m"``, ``"N*s/m"``.
    """

    unit: str

    @property
    def dim(self) -> Dimension:
        """The dimension of :attr:`unit`."""
        return parse_unit(self.unit)[1]

    def convert(self, value: Any) -> Any:
        """Convert a written quantity (or a sequence of them) to SI floats.

        Strings such as ``"20 mm"`` and :class:`Quantity` values are checked
        against this unit's dimension; bare numbers are taken as SI already.
        Anything else is returned unchanged for pydantic to reject.

        Raises:
            pydantic_core.PydanticCustomError: ``unit_mismatch`` (wrong dimension or
                unknown unit).
        """
        if isinstance(value, (list, tuple)):
            return type(value)(self._convert_one(v) for v in value)
        return self._convert_one(value)

    def _convert_one(self, value: Any) -> Any:
        from pydantic_core import PydanticCustomError

        if isinstance(value, str) and _NUMBER_ONLY.match(value):
            value = float(value)  # YAML 1.1 reads 1e5 as text; a bare number is SI
        if isinstance(value, float) and not math.isfinite(value):
            raise PydanticCustomError(
                "finite_number", "expected a finite number, found {value}", {"value": value}
            )
        if isinstance(value, float):
            return value
        if isinstance(value, str):
            try:
                value = parse_quantity(value)
            except UnitError as exc:
                raise PydanticCustomError("unit_mismatch", "{msg}", {"msg": exc.message}) from exc
        if isinstance(value, Quantity):
            if value.dim != self.dim:
                raise PydanticCustomError(
                    "unit_mismatch",
                    "expected {expected} (unit {unit}), found {found}",
                    {
                        "expected": dimension_name(self.dim),
                        "unit": self.unit,
                        "found": dimension_name(value.dim),
                    },
                )
            if not math.isfinite(value.value):
                raise PydanticCustomError(
                    "finite_number", "expected a finite number, found {value}", {"value": value}
                )
            return value.value
        return value

    def __get_pydantic_core_schema__(self, source: Any, handler: Any) -> Any:
        from pydantic_core import core_schema

        one = {"anyOf": [{"type": "number"}, {"type": "string", "pattern": _PATTERN}]}
        origin = getattr(source, "__origin__", None)
        input_schema: dict[str, Any] = (
            {"type": "array", "items": one} if origin in (tuple, list) else one
        )
        return core_schema.no_info_before_validator_function(
            self.convert,
            handler(source),
            json_schema_input_schema=core_schema.any_schema(
                metadata={"pydantic_js_functions": [lambda _s, _h: input_schema]}
            ),
        )


Length = Annotated[float, Unit("m")]
"""A length [m]."""
Angle = Annotated[float, Unit("rad")]
"""An angle [rad]."""
Force = Annotated[float, Unit("N")]
"""A force or tension [N]."""
Duration = Annotated[float, Unit("s")]
"""A duration [s]."""
Mass = Annotated[float, Unit("kg")]
"""A mass [kg]."""
Speed = Annotated[float, Unit("m/s")]
"""A linear speed [m/s]."""
AngularSpeed = Annotated[float, Unit("rad/s")]
"""An angular speed [rad/s]."""
Acceleration = Annotated[float, Unit("m/s^2")]
"""A linear acceleration [m/s^2]."""
Stiffness = Annotated[float, Unit("N/m")]
"""A stiffness [N/m]."""
Damping = Annotated[float, Unit("N*s/m")]
"""A damping [N*s/m]."""
Rate = Annotated[float, Unit("1/s")]
"""A rate [1/s]."""
LinearDensity = Annotated[float, Unit("kg/m")]
"""A mass per length [kg/m]."""
Position = Annotated[tuple[float, float, float], Unit("m")]
"""A point (x, y, z) [m]."""
