"""The safe ${...} evaluator: values, dimensions, and everything it refuses."""

from __future__ import annotations

import math

import pytest

from suture_engine.language.expressions import ExpressionError, Namespace, evaluate
from suture_engine.language.units import Quantity, parse_unit

NEWTON = parse_unit("N")[1]
NAMES = {
    "mirror": True,
    "turns": 2,
    "suture": Namespace("suture", {"knot_pull_strength": Quantity(14.1, NEWTON)}),
    "scene": Namespace("scene", {"tension_limit": Quantity(7.0, NEWTON)}),
}


def test_mirror_idiom_and_quantities() -> None:
    q = evaluate("mirror and -180 deg or 180 deg", NAMES)
    assert isinstance(q, Quantity) and q.value == pytest.approx(-math.pi)
    q = evaluate("turns * (mirror and -180 deg or 180 deg)", NAMES)
    assert q.value == pytest.approx(-2 * math.pi)


def test_namespaces_and_arithmetic() -> None:
    q = evaluate("0.8 * suture.knot_pull_strength", NAMES)
    assert q.value == pytest.approx(0.8 * 14.1) and q.dim == NEWTON
    assert evaluate("min(scene.tension_limit, 3 N)", NAMES).value == pytest.approx(3.0)
    assert evaluate("2000 N*s/m", NAMES).dim == parse_unit("N*s/m")[1]
    assert evaluate("'a' if turns > 1 else 'b'", NAMES) == "a"
    assert evaluate("5 mm + 2 mm", NAMES).value == pytest.approx(0.007)


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('true')",
        "().__class__.__bases__",
        "suture.__dict__",
        "suture._values",
        "open('/etc/passwd')",
        "[x for x in range(10)]",
        "lambda: 1",
        "mirror[0]",
        "3 N + 2 mm",
        "1 / 0",
        "10 ** 10 ** 10",
        "unknown_name",
        "suture.nothing",
        "(1 +",
        "'a' * 1000000",
        "f'{mirror}'",
        "x := 3",
        "sin(3 N)",
    ],
)
def test_refused(text: str) -> None:
    with pytest.raises(ExpressionError) as info:
        evaluate(text, NAMES)
    assert info.value.code == "bad-expression"
