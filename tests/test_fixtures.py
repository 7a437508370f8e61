"""Virtual fixtures: constraint Jacobians against central finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from suture_engine.control.fixtures import (
    Circle,
    Cone,
    EqualityFixture,
    Fixture,
    FixtureError,
    Line,
    Plane,
)

FIXTURES: list[Fixture] = [
    Line(),
    Line(point=[0.01, -0.02, 0.1], direction=[1.0, 1.0, -2.0], thesis_form=True),
    Line(point=[0.0, 0.0, 0.0], direction=[0.0, 0.0, 1.0]),
    Circle(),
    Circle(center=[0.0, 0.0, 0.15], radius=0.05),
    Circle(center=[0.02, -0.01, 0.12], radius=0.03, normal=[1.0, 2.0, 3.0]),
    Plane(point=[0.0, 0.0, 0.1], normal=[1.0, 1.0, 1.0]),
    Cone(apex=[0.0, 0.0, 0.0], axis=[0.0, 0.0, 1.0], half_angle=0.6),
]


def _numeric(fn, x: np.ndarray, h: float = 1e-6) -> np.ndarray:  # type: ignore[no-untyped-def]
    cols = [(fn(x + h * e) - fn(x - h * e)) / (2 * h) for e in np.eye(4)]
    return np.array(cols).T


def _points(seed: int, n: int = 25) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    pts = rng.normal(scale=0.08, size=(n, 4))
    pts[:, 2] += 0.12
    pts[:, 3] = rng.uniform(-np.pi, np.pi, size=n)
    return list(pts)


@pytest.mark.parametrize("fx", FIXTURES, ids=lambda f: f.name)
def test_constraint_jacobian_matches_central_differences(fx: Fixture) -> None:
    for x in _points(1):
        jc = fx.jacobian(x)
        assert jc.shape == (fx.rows, 4)
        np.testing.assert_allclose(jc, _numeric(fx.value, x), atol=1e-7, rtol=1e-6)


@pytest.mark.parametrize("fx", [f for f in FIXTURES if isinstance(f, EqualityFixture)], ids=str)
def test_free_map_jacobian_and_diffeomorphism(fx: EqualityFixture) -> None:
    for x in _points(2):
        np.testing.assert_allclose(fx.free_jacobian(x), _numeric(fx.free, x), atol=1e-7, rtol=1e-6)
        # d^-1(d(x)) = x (6.34): d is a bijection on this neighbourhood.
        back = fx.inverse(fx.value(x), fx.free(x))
        np.testing.assert_allclose(back, x, atol=1e-12)
        # The projection (6.35) lies on the constraint set and keeps the free coordinates.
        p = fx.project(x)
        np.testing.assert_allclose(fx.value(p), 0.0, atol=1e-12)
        f_p, f_x = fx.free(p), fx.free(x)
        np.testing.assert_allclose(f_p, f_x, atol=1e-12)
        # [Jc; Jf] is invertible (needed by (6.36)).
        d = np.vstack([fx.jacobian(x), fx.free_jacobian(x)])
        assert abs(np.linalg.det(d)) > 1e-9


def test_thesis_line_rows_are_6_31() -> None:
    # Table 6.1: a = (1, 1, -2); (6.32): Jc = [[1/a1, -1/a2, 0, 0], [1/a1, 0, -1/a3, 0]].
    line = Line(direction=[1.0, 1.0, -2.0], thesis_form=True)
    np.testing.assert_allclose(line.jacobian(np.zeros(4)), [[1, -1, 0, 0], [1, 0, 0.5, 0]])
    on_line = np.array([0.05, 0.05, -0.1, 0.3])
    np.testing.assert_allclose(line.value(on_line), 0.0, atol=1e-15)
    off = np.array([0.05, 0.06, -0.1, 0.0])  # x/a1 - y/a2 = -0.01, x/a1 - z/a3 = 0
    np.testing.assert_allclose(line.value(off), [-0.01, 0.0], atol=1e-15)


def test_metric_line_rows_are_distances() -> None:
    line = Line(point=[0.0, 0.0, 0.1], direction=[1.0, 1.0, 2.0])
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.normal(size=4) * 0.1
        d = x[:3] - line.point
        a = line.direction / np.linalg.norm(line.direction)
        dist = np.linalg.norm(d - (d @ a) * a)
        assert np.linalg.norm(line.value(x)) == pytest.approx(dist, rel=1e-12)


def test_circle_rows_match_6_45_and_radial_deviation() -> None:
    c = Circle(center=[0.0, 0.0, 0.15], radius=0.05)
    x = np.array([0.0, 0.052, 0.151, 0.0])
    # (6.45) scaled by 1/(2r): ((x-x0)^2 + (y-y0)^2 - r^2) / (2r), z - z0.
    np.testing.assert_allclose(c.value(x), [(0.052**2 - 0.05**2) / 0.1, 0.001], rtol=1e-12)
    assert c.value(x)[0] == pytest.approx(0.002, rel=0.05)  # ~ radial deviation [m]
    # (6.46) scaled: Jc = [[2(x-x0), 2(y-y0), 0, 0] / (2r), [0, 0, 1, 0]].
    np.testing.assert_allclose(c.jacobian(x), [[0, 0.052 / 0.05, 0, 0], [0, 0, 1, 0]])
    # (6.49): theta = atan2(y, x).
    assert c.free(x)[0] == pytest.approx(np.pi / 2)


def test_cone_sign() -> None:
    cone = Cone(apex=[0.0, 0.0, 0.0], axis=[0.0, 0.0, 1.0], half_angle=0.5)
    assert cone.value(np.array([0.0, 0.0, 0.1, 0.0]))[0] < 0  # on the axis: inside
    assert cone.value(np.array([0.1, 0.0, 0.01, 0.0]))[0] > 0  # far off axis: outside
    edge = np.array([np.sin(0.5), 0.0, np.cos(0.5), 0.0]) * 0.1
    assert cone.value(edge)[0] == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: Line(direction=[0.0, 0.0, 0.0]), "direction"),
        (lambda: Line(direction=[1.0, 0.0, 1.0], thesis_form=True), "direction"),
        (lambda: Circle(radius=-1.0), "radius"),
        (lambda: Plane(normal=[float("nan"), 0.0, 1.0]), "normal"),
        (lambda: Cone(half_angle=2.0), "half_angle"),
    ],
)
def test_bad_geometry_is_a_typed_error(build, field: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(FixtureError) as err:
        build()
    assert err.value.field == field
    assert err.value.code == "bad-fixture"


@pytest.mark.parametrize("fx", FIXTURES, ids=lambda f: f.name)
def test_linearize_is_value_and_jacobian(fx: Fixture) -> None:
    for x in _points(4, n=5):
        c, jc = fx.linearize(x)
        np.testing.assert_allclose(c, fx.value(x), atol=1e-15)
        np.testing.assert_allclose(jc, fx.jacobian(x), atol=1e-15)
