"""Units: the fast table against pint (the oracle), dimensions, and the pydantic marker."""

from __future__ import annotations

import math

import pint
import pytest
from pydantic import BaseModel, ValidationError

from suture_engine.language.units import (
    Force,
    Length,
    Position,
    Quantity,
    UnitError,
    parse_quantity,
    parse_unit,
)

UREG = pint.UnitRegistry()


@pytest.mark.parametrize(
    "text",
    [
        "20 mm",
        "3 N",
        "2000 N*s/m",
        "5 mm/s",
        "2 ms",
        "10 N/m",
        "1 kg",
        "3 mm/s^2",
        "0.5 kN",
        "1 Hz",
    ],
)
def test_table_matches_pint(text: str) -> None:
    q = parse_quantity(text)
    expected = UREG.Quantity(text).to_base_units()
    assert q.value == pytest.approx(float(expected.magnitude), rel=1e-12)


def test_angles_are_their_own_dimension() -> None:
    q = parse_quantity("180 deg")
    assert q.value == pytest.approx(math.pi)
    assert q.dim != parse_quantity("1 m").dim
    assert q.dim == parse_unit("rad")[1]


def test_a_bare_number_is_dimensionless() -> None:
    assert parse_quantity("20") == Quantity(20.0, (0, 0, 0, 0))


def test_units_outside_the_table_fall_back_to_pint() -> None:
    assert parse_quantity("1 inch").value == pytest.approx(0.0254)
    assert parse_quantity("1 inch").dim == parse_unit("m")[1]


@pytest.mark.parametrize("text", ["20 furlongs_per_fortnightx", "mm", "", "3 N*", "x N"])
def test_bad_quantities_raise_unit_error(text: str) -> None:
    with pytest.raises(UnitError):
        parse_quantity(text)


class _Model(BaseModel):
    length: Length
    force: Force = 1.0
    where: Position = (0.0, 0.0, 0.0)


def test_marker_converts_to_si_once() -> None:
    m = _Model.model_validate({"length": "20 mm", "force": "0.5 kN", "where": ["1 cm", 0, "2 mm"]})
    assert m.length == pytest.approx(0.02)
    assert m.force == pytest.approx(500.0)
    assert m.where == pytest.approx((0.01, 0.0, 0.002))


def test_marker_accepts_quantities_and_bare_si_numbers() -> None:
    m = _Model.model_validate({"length": Quantity(0.03, parse_unit("m")[1]), "force": 2})
    assert (m.length, m.force) == (0.03, 2.0)


def test_marker_rejects_the_wrong_dimension_with_unit_mismatch() -> None:
    with pytest.raises(ValidationError) as info:
        _Model.model_validate({"length": "180 deg"})
    (err,) = info.value.errors()
    assert err["type"] == "unit_mismatch"
    assert err["loc"] == ("length",)
    assert "length" in err["msg"] and "angle" in err["msg"]
