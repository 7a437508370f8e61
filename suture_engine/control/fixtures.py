"""Virtual fixtures: holonomic constraints C(x) = 0 on the task variables (thesis 6.1).

The task variables of one EndoBot are ``x = (x, y, z, phi)``: the tool-tip position
[m] and the roll angle [rad] (3.13). A fixture is a constraint function ``C(x)`` with
its constraint Jacobian ``Jc = dC/dx`` (6.2). Equality fixtures (line, circle, plane)
also carry the complementary free-motion map ``f(x)`` and the inverse of the
diffeomorphism ``d = [c; f]`` (6.34) that joint-space shared control needs (6.35-6.36).
The cone is an inequality ``g(x) <= 0``.

Every row is scaled so that it reads as a length [m] near the constraint set: a gain on
it is then a stiffness [N/m] and a deviation from it is a distance [m]. (The one
exception is ``Line(thesis_form=True)``, which keeps the rows of (6.31) verbatim.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError

__all__ = [
    "Circle",
    "Cone",
    "EqualityFixture",
    "Fixture",
    "FixtureError",
    "Line",
    "Plane",
]

Array = NDArray[np.float64]


class FixtureError(SutureError):
    """A fixture was given geometry it cannot represent.

    Attributes:
        fixture: the fixture kind (``"line"``, ``"circle"``...).
        field: the offending field name.
        value: the offending value.
    """

    code = "bad-fixture"

    def __init__(self, fixture: str, field: str, value: object, reason: str) -> None:
        super().__init__(f"{fixture}: {field}={value!r}: {reason}")
        self.fixture = fixture
        self.field = field
        self.value = value


def _unit(vec: object, fixture: str, name: str) -> Array:
    v = np.asarray(vec, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise FixtureError(fixture, name, vec, "expected a finite 3-vector")
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise FixtureError(fixture, name, vec, "must not be the zero vector")
    return v / n


def _point(vec: object, fixture: str, name: str) -> Array:
    v = np.asarray(vec, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise FixtureError(fixture, name, vec, "expected a finite 3-vector")
    return v


def _orthonormal_complement(axis: Array) -> tuple[Array, Array]:
    """Two unit vectors u, v with (u, v, axis) a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, axis)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    return u, v


@dataclass(frozen=True, eq=False)
class Fixture:
    """Base class of virtual fixtures; subclasses implement ``value`` and ``jacobian``.

    Attributes:
        kind: ``"eq"`` for C(x) = 0, ``"ineq"`` for g(x) <= 0.
        rows: the number of constraint rows m.
        name: a label used in QP reports (``"line"``).
    """

    kind: Literal["eq", "ineq"] = field(init=False, default="eq")
    rows: int = field(init=False, default=0)
    name: str = field(init=False, default="fixture")

    def value(self, x: Array) -> Array:
        """C(x) (6.1) for the task vector x = (x, y, z, phi) [m, m, m, rad]; shape (m,)."""
        raise NotImplementedError

    def jacobian(self, x: Array) -> Array:
        """Constraint Jacobian Jc(x) = dC/dx (6.2), shape (m, 4)."""
        raise NotImplementedError

    def linearize(self, x: Array) -> tuple[Array, Array]:
        """C(x) and Jc(x) together (the per-tick call of the QP); treat both as read-only."""
        return self.value(x), self.jacobian(x)

    def affine(self) -> tuple[Array, Array] | None:
        """``(Jc, p0)`` when ``C(x) = Jc[:, :3] (p - p0)`` with a constant Jc (m, 4) whose
        roll column is zero and a point p0 [m] (a line, a plane), else None: the QP then
        evaluates the rows itself."""
        return None


@dataclass(frozen=True, eq=False)
class EqualityFixture(Fixture):
    """An equality fixture with a complementary free-motion map f (6.34)."""

    def free(self, x: Array) -> Array:
        """Free-motion coordinates f(x) (6.34); shape (4 - m,)."""
        raise NotImplementedError

    def free_jacobian(self, x: Array) -> Array:
        """Jf(x) = df/dx (6.36), shape (4 - m, 4)."""
        raise NotImplementedError

    def inverse(self, c: Array, f: Array) -> Array:
        """The inverse map x = d^-1([c; f]) of the diffeomorphism d = [c; f] (6.34-6.35)."""
        raise NotImplementedError

    def project(self, x: Array) -> Array:
        """The constraint-set point with the same free coordinates, d^-1([0; f(x)]) (6.35)."""
        return self.inverse(np.zeros(self.rows), self.free(x))

    def inverse_stacked(self, cf: Array) -> Array:
        """:meth:`inverse` of ``[c; f]`` given stacked in one array, shape (4,) (a
        per-tick form: ``cf`` is not kept)."""
        return self.inverse(cf[: self.rows], cf[self.rows :])

    def affine_inverse(self) -> tuple[Array, Array] | None:
        """``(D, p0)`` when the inverse map is affine, ``d^-1([c; f]) = D [c; f] + (p0, 0)``
        with D (4, 4) and p0 [m] (a line, a plane), else None (a circle)."""
        return None


@dataclass(frozen=True, eq=False)
class Line(EqualityFixture):
    """The tip stays on a straight line; the roll is free (6.25-6.32, 6.38-6.42).

    With ``thesis_form=True`` the rows are exactly (6.31): ``x/a1 - y/a2`` and
    ``x/a1 - z/a3`` about ``point`` (every direction component must be non-zero), with the
    free map (6.40) ``f = (a . p, phi)``. Otherwise (default) the rows are the distances
    along two orthonormal normals ``n_i . (p - p0)``, so the gain on them is a stiffness
    [N/m] whatever the direction.

    Args:
        point: a point of the line, p0 [m].
        direction: its direction a (any length; (1, 1, -2) in Table 6.1).
        thesis_form: use the rows of (6.31) instead of orthonormal distances.
    """

    point: Array = field(default_factory=lambda: np.zeros(3))
    direction: Array = field(default_factory=lambda: np.array([1.0, 1.0, -2.0]))
    thesis_form: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _point(self.point, "line", "point"))
        a = np.asarray(self.direction, dtype=float).reshape(-1)
        unit = _unit(a, "line", "direction")
        if self.thesis_form and np.any(np.abs(a) < 1e-12):
            raise FixtureError("line", "direction", a, "(6.31) needs a1, a2, a3 all non-zero")
        object.__setattr__(self, "direction", a)
        object.__setattr__(self, "rows", 2)
        object.__setattr__(self, "name", "line")
        object.__setattr__(self, "kind", "eq")
        n1, n2 = _orthonormal_complement(unit)
        jc = np.zeros((2, 4))
        if self.thesis_form:
            a1, a2, a3 = a
            jc[0, :3] = (1.0 / a1, -1.0 / a2, 0.0)
            jc[1, :3] = (1.0 / a1, 0.0, -1.0 / a3)
        else:
            jc[0, :3] = n1
            jc[1, :3] = n2
        jf = np.zeros((2, 4))
        jf[0, :3] = a if self.thesis_form else unit
        jf[1, 3] = 1.0
        object.__setattr__(self, "_jc", jc)
        object.__setattr__(self, "_jf", jf)
        object.__setattr__(self, "_dinv", np.linalg.inv(np.vstack([jc, jf])))

    def value(self, x: Array) -> Array:
        """C(x) (6.31) [m]."""
        d = np.asarray(x, dtype=float)[:3] - self.point
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc[:, :3] @ d

    def jacobian(self, x: Array) -> Array:
        """Jc (6.32): constant, shape (2, 4)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc.copy()

    def linearize(self, x: Array) -> tuple[Array, Array]:
        """C(x) and the constant Jc (shared, read-only)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc[:, :3] @ (x[:3] - self.point), jc

    def affine(self) -> tuple[Array, Array]:
        """``(Jc, p0)``: the rows are ``Jc[:, :3] (p - p0)`` (shared, read-only)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc, self.point

    def free(self, x: Array) -> Array:
        """f(x) = (arc length along the line, roll) (6.40) [m, rad]."""
        xx = np.asarray(x, dtype=float)
        d = np.concatenate([xx[:3] - self.point, xx[3:4]])
        jf: Array = self._jf  # type: ignore[attr-defined]
        return jf @ d

    def free_jacobian(self, x: Array) -> Array:
        """Jf (6.42): constant, shape (2, 4)."""
        jf: Array = self._jf  # type: ignore[attr-defined]
        return jf.copy()

    def inverse(self, c: Array, f: Array) -> Array:
        """d^-1 of the linear map d = [Jc; Jf] (x - (p0, 0)) (6.39-6.40)."""
        return self.inverse_stacked(np.concatenate([np.asarray(c, float), np.asarray(f, float)]))

    def inverse_stacked(self, cf: Array) -> Array:
        """:meth:`inverse` of the stacked ``[c; f]`` (4,) [m, m, m, rad]: one product."""
        dinv: Array = self._dinv  # type: ignore[attr-defined]
        out = dinv @ cf
        out[:3] += self.point
        return out

    def affine_inverse(self) -> tuple[Array, Array]:
        """``(D, p0)``: ``d^-1([c; f]) = D [c; f] + (p0, 0)`` (shared, read-only)."""
        dinv: Array = self._dinv  # type: ignore[attr-defined]
        return dinv, self.point


@dataclass(frozen=True, eq=False)
class Circle(EqualityFixture):
    """The tip stays on a circle; the roll is free (6.43-6.51).

    Rows: ``c1 = (rho^2 - r^2) / (2 r)`` with rho the distance from the axis through the
    centre (this is (6.43) scaled by 1/(2r), so that near the circle it equals the radial
    deviation rho - r [m]), and ``c2 = n . (p - p0)`` (6.44). With the default normal
    (0, 0, 1) the Jacobian is (6.46) up to that scale. Free map (6.49-6.50):
    ``f = (theta, phi)`` with theta the angle about the normal.

    Args:
        center: the centre p0 [m] ((0, 0, -0.15) in Fig. 6.14).
        radius: r [m] (0.05 in Fig. 6.14).
        normal: the normal of the circle's plane (default z).
    """

    center: Array = field(default_factory=lambda: np.array([0.0, 0.0, -0.15]))
    radius: float = 0.05
    normal: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _point(self.center, "circle", "center"))
        if not (np.isfinite(self.radius) and self.radius > 0.0):
            raise FixtureError("circle", "radius", self.radius, "must be a positive length [m]")
        n = _unit(self.normal, "circle", "normal")
        object.__setattr__(self, "normal", n)
        u, v = _orthonormal_complement(n)
        if abs(n[2]) > 0.9:  # keep theta = atan2(y, x) of (6.49) for the thesis' x-y circle
            u, v = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
            if n[2] < 0:
                v = -v
            u = u - (u @ n) * n
            u /= np.linalg.norm(u)
            v = np.cross(n, u)
        object.__setattr__(self, "_u", u)
        object.__setattr__(self, "_v", v)
        object.__setattr__(self, "rows", 2)
        object.__setattr__(self, "name", "circle")
        object.__setattr__(self, "kind", "eq")

    def _planar(self, x: Array) -> tuple[float, float, float]:
        d = np.asarray(x, dtype=float)[:3] - self.center
        u: Array = self._u  # type: ignore[attr-defined]
        v: Array = self._v  # type: ignore[attr-defined]
        return float(d @ u), float(d @ v), float(d @ self.normal)

    def value(self, x: Array) -> Array:
        """C(x) (6.45), first row scaled by 1/(2r) [m]."""
        a, b, h = self._planar(x)
        r = self.radius
        return np.array([(a * a + b * b - r * r) / (2.0 * r), h])

    def jacobian(self, x: Array) -> Array:
        """Jc(x) (6.46), first row scaled by 1/(2r); shape (2, 4)."""
        a, b, _ = self._planar(x)
        u: Array = self._u  # type: ignore[attr-defined]
        v: Array = self._v  # type: ignore[attr-defined]
        jc = np.zeros((2, 4))
        jc[0, :3] = (a * u + b * v) / self.radius
        jc[1, :3] = self.normal
        return jc

    def free(self, x: Array) -> Array:
        """f(x) = (theta, phi) (6.49-6.50) [rad, rad]."""
        a, b, _ = self._planar(x)
        return np.array([math.atan2(float(b), float(a)), float(np.asarray(x, dtype=float)[3])])

    def free_jacobian(self, x: Array) -> Array:
        """Jf(x) (6.51) with rho^2 in the denominator (exact away from the circle too)."""
        a, b, _ = self._planar(x)
        rho2 = max(a * a + b * b, 1e-18)
        u: Array = self._u  # type: ignore[attr-defined]
        v: Array = self._v  # type: ignore[attr-defined]
        jf = np.zeros((2, 4))
        jf[0, :3] = (a * v - b * u) / rho2
        jf[1, 3] = 1.0
        return jf

    def inverse(self, c: Array, f: Array) -> Array:
        """d^-1([c; f]): rho = sqrt(r^2 + 2 r c1), height c2, angle theta, roll phi."""
        c1, c2 = (float(c[0]), float(c[1]))
        theta, phi = (float(f[0]), float(f[1]))
        rho = float(np.sqrt(max(self.radius**2 + 2.0 * self.radius * c1, 0.0)))
        u: Array = self._u  # type: ignore[attr-defined]
        v: Array = self._v  # type: ignore[attr-defined]
        p = self.center + rho * (math.cos(theta) * u + math.sin(theta) * v) + c2 * self.normal
        return np.array([p[0], p[1], p[2], phi])


@dataclass(frozen=True, eq=False)
class Plane(EqualityFixture):
    """The tip stays on a plane ``n . (p - p0) = 0`` [m]; in-plane motion and roll are free.

    Args:
        point: a point of the plane p0 [m].
        normal: the plane's normal (any length).
    """

    point: Array = field(default_factory=lambda: np.zeros(3))
    normal: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _point(self.point, "plane", "point"))
        n = _unit(self.normal, "plane", "normal")
        object.__setattr__(self, "normal", n)
        u, v = _orthonormal_complement(n)
        jc = np.zeros((1, 4))
        jc[0, :3] = n
        jf = np.zeros((3, 4))
        jf[0, :3] = u
        jf[1, :3] = v
        jf[2, 3] = 1.0
        object.__setattr__(self, "_jc", jc)
        object.__setattr__(self, "_jf", jf)
        object.__setattr__(self, "rows", 1)
        object.__setattr__(self, "name", "plane")
        object.__setattr__(self, "kind", "eq")

    def value(self, x: Array) -> Array:
        """C(x) = n . (p - p0) [m]; shape (1,)."""
        return np.array([float(self.normal @ (np.asarray(x, dtype=float)[:3] - self.point))])

    def jacobian(self, x: Array) -> Array:
        """Jc = [n^T, 0]; shape (1, 4)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc.copy()

    def linearize(self, x: Array) -> tuple[Array, Array]:
        """C(x) and the constant Jc (shared, read-only)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc[:, :3] @ (x[:3] - self.point), jc

    def affine(self) -> tuple[Array, Array]:
        """``(Jc, p0)``: the rows are ``Jc[:, :3] (p - p0)`` (shared, read-only)."""
        jc: Array = self._jc  # type: ignore[attr-defined]
        return jc, self.point

    def free(self, x: Array) -> Array:
        """f(x) = (u . (p - p0), v . (p - p0), phi) [m, m, rad]."""
        xx = np.asarray(x, dtype=float)
        jf: Array = self._jf  # type: ignore[attr-defined]
        return jf @ np.concatenate([xx[:3] - self.point, xx[3:4]])

    def free_jacobian(self, x: Array) -> Array:
        """Jf: constant, shape (3, 4)."""
        jf: Array = self._jf  # type: ignore[attr-defined]
        return jf.copy()

    def inverse(self, c: Array, f: Array) -> Array:
        """d^-1([c; f]) = p0 + c n + f1 u + f2 v, roll f3."""
        jf: Array = self._jf  # type: ignore[attr-defined]
        p = self.point + float(c[0]) * self.normal + f[0] * jf[0, :3] + f[1] * jf[1, :3]
        return np.array([p[0], p[1], p[2], float(f[2])])

    def affine_inverse(self) -> tuple[Array, Array]:
        """``(D, p0)``: ``d^-1([c; f]) = D [c; f] + (p0, 0)``, D's columns (n, u, v, e_roll)."""
        jf: Array = self._jf  # type: ignore[attr-defined]
        d = np.zeros((4, 4))
        d[:3, 0] = self.normal
        d[:3, 1] = jf[0, :3]
        d[:3, 2] = jf[1, :3]
        d[3, 3] = 1.0
        return d, self.point


@dataclass(frozen=True, eq=False)
class Cone(Fixture):
    """The tip stays inside a half-angle cone about an axis through an apex (inequality).

    ``g(x) = cos(alpha) |p - a| - axis . (p - a) <= 0`` [m]: zero on the cone's surface,
    negative inside, and for a point just outside it approximately cos(alpha) times the
    distance to the surface.

    Args:
        apex: the apex a [m].
        axis: the cone's axis, pointing into the cone (any length).
        half_angle: alpha [rad], in (0, pi/2).
    """

    apex: Array = field(default_factory=lambda: np.zeros(3))
    axis: Array = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    half_angle: float = 0.5

    def __post_init__(self) -> None:
        object.__setattr__(self, "apex", _point(self.apex, "cone", "apex"))
        object.__setattr__(self, "axis", _unit(self.axis, "cone", "axis"))
        if not (0.0 < self.half_angle < np.pi / 2):
            raise FixtureError("cone", "half_angle", self.half_angle, "must be in (0, pi/2) [rad]")
        object.__setattr__(self, "_axis_t", tuple(float(v) for v in self.axis))
        object.__setattr__(self, "_apex_t", tuple(float(v) for v in self.apex))
        object.__setattr__(self, "_cos_t", math.cos(self.half_angle))
        object.__setattr__(self, "rows", 1)
        object.__setattr__(self, "name", "cone")
        object.__setattr__(self, "kind", "ineq")

    def value(self, x: Array) -> Array:
        """g(x) [m]; shape (1,)."""
        d = np.asarray(x, dtype=float)[:3] - self.apex
        return np.array([math.cos(self.half_angle) * np.linalg.norm(d) - float(self.axis @ d)])

    def linearize(self, x: Array) -> tuple[Array, Array]:
        """g(x) and dg/dx in one pass on plain floats."""
        ax, ay, az = self._axis_t  # type: ignore[attr-defined]
        px, py, pz = self._apex_t  # type: ignore[attr-defined]
        ca = self._cos_t  # type: ignore[attr-defined]
        dx, dy, dz = float(x[0]) - px, float(x[1]) - py, float(x[2]) - pz
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        g = ca * dist - (ax * dx + ay * dy + az * dz)
        k = ca / dist if dist > 1e-12 else 0.0
        return np.array([g]), np.array([[k * dx - ax, k * dy - ay, k * dz - az, 0.0]])

    def jacobian(self, x: Array) -> Array:
        """dg/dx; at the apex the (sub)gradient -axis is used. Shape (1, 4)."""
        d = np.asarray(x, dtype=float)[:3] - self.apex
        dist = float(np.linalg.norm(d))
        jc = np.zeros((1, 4))
        radial = d / dist if dist > 1e-12 else np.zeros(3)
        jc[0, :3] = math.cos(self.half_angle) * radial - self.axis
        return jc
