"""Hand-built suture centerlines with a known knot, for tests and examples.

Every function returns an open N x 3 polyline (dimensionless, about unit
size; scale it to metres as needed). The open curves are built so that the
classifier's far-away closure gives the intended knot:

- :func:`trefoil` and :func:`figure_eight`: closed parametric knots cut
  open at their outermost point;
- :func:`long_knot`: a knot laid along the x axis (ends far out at +-x);
- :func:`connected_sum`: two long knots one after the other (square knot =
  trefoil # mirror trefoil, granny knot = trefoil # trefoil);
- :func:`overhand`: a strand whose end goes through its own loop once (overhand,
  trefoil) or twice (double overhand, a surgeon's first throw), built as a
  surgeon ties it; :func:`surgeons_knot` joins a double and a single throw;
- :func:`wobbly_unknot`: an unknot with many projected crossings;
- :func:`half_hitches`: a straight post strand with a second strand wrapped
  around it, the capsized square knot of thesis Fig. 7.4 (geometry only).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "connected_sum",
    "figure_eight",
    "granny_knot",
    "half_hitches",
    "long_knot",
    "overhand",
    "square_knot",
    "surgeons_knot",
    "trefoil",
    "wobbly_unknot",
]


def _cut_outermost(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    k = int(np.argmax(np.linalg.norm(pts[:, :2], axis=1)))
    return np.roll(pts, -k, axis=0)[1:]


def trefoil(n: int = 100, *, right: bool = True) -> NDArray[np.float64]:
    """(2,3) torus knot ``((2 + cos 3t) cos 2t, (2 + cos 3t) sin 2t, -+sin 3t)``, cut open.

    Args:
        n: number of samples of the closed curve.
        right: right-handed (positive crossings, v3 = +1) or left-handed.
    """
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    r = 2.0 + np.cos(3.0 * t)
    z = np.sin(3.0 * t) * (-1.0 if right else 1.0)
    return _cut_outermost(np.c_[r * np.cos(2.0 * t), r * np.sin(2.0 * t), z])


def figure_eight(n: int = 120) -> NDArray[np.float64]:
    """Figure-eight knot ``((2 + cos 2t) cos 3t, (2 + cos 2t) sin 3t, sin 4t)``, cut open."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    r = 2.0 + np.cos(2.0 * t)
    return _cut_outermost(np.c_[r * np.cos(3.0 * t), r * np.sin(3.0 * t), np.sin(4.0 * t)])


def long_knot(
    cut_curve: NDArray[np.float64], *, reach: float = 12.0, lift: float = 3.0
) -> NDArray[np.float64]:
    """Lay a cut-open knot along the x axis.

    The cut is turned to the -x side; the first end runs straight to
    ``(-reach, 0, 0)``, the last end rises to ``z = lift`` (above the whole
    knot), passes over it and comes down to ``(+reach, 0, 0)``.
    """
    gap = 0.5 * (cut_curve[0] + cut_curve[-1])
    ang = np.pi - np.arctan2(gap[1], gap[0])
    c, s = np.cos(ang), np.sin(ang)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    p = cut_curve @ rot.T
    xmin, xmax = float(p[:, 0].min()), float(p[:, 0].max())
    head = np.array([[-reach, 0.0, 0.0], [xmin - 1.5, p[0, 1], p[0, 2]]])
    tail = np.array(
        [
            [p[-1, 0] - 1.0, p[-1, 1], lift],
            [xmax + 1.0, 0.0, lift],
            [xmax + 2.0, 0.0, 0.0],
            [reach, 0.0, 0.0],
        ]
    )
    return np.vstack([head, p, tail])


def connected_sum(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Two long knots (see :func:`long_knot`) joined end to start along x."""
    first = a - np.array([a[:, 0].max(), 0.0, 0.0])
    second = b - np.array([b[:, 0].min(), 0.0, 0.0])
    return np.vstack([first, second[1:]])


def square_knot(n: int = 100, *, right_first: bool = True) -> NDArray[np.float64]:
    """Square (reef) knot: trefoil # mirror trefoil."""
    return connected_sum(
        long_knot(trefoil(n, right=right_first)), long_knot(trefoil(n, right=not right_first))
    )


def granny_knot(n: int = 100, *, right: bool = True) -> NDArray[np.float64]:
    """Granny knot: trefoil # trefoil of the same handedness."""
    return connected_sum(long_knot(trefoil(n, right=right)), long_knot(trefoil(n, right=right)))


def overhand(turns: int = 1, *, right: bool = True, n: int = 12) -> NDArray[np.float64]:
    """A long knot tied as a hand ties it: a loop, and the end through it ``turns`` times.

    The standing part comes in along -x (at y = -1) to the bottom of a unit loop in
    the z = 0 plane, goes once round it counter-clockwise and rises at the end of the
    lap to pass over itself. The end then winds ``turns`` times round the loop's right
    side (radius 0.3 about the loop's own strand), so that it goes through the loop
    once per turn, and leaves over the top to +x. No knot type is put in by hand: one
    turn is an overhand knot, two a double overhand (a surgeon's first throw).

    Args:
        turns: passes of the end through the loop (>= 1).
        right: the right-handed knot (trefoil v3 = +1) or its mirror image.
        n: samples per quarter of the loop (twice as many per turn of the end).
    """
    if turns < 1:
        raise ValueError(f"turns must be >= 1, got {turns}")
    standing = np.c_[np.linspace(-6.0, 0.0, 8)[:-1], np.full(7, -1.0), np.zeros(7)]
    s = np.linspace(-0.5 * np.pi, 1.5 * np.pi, 4 * n)
    lap = np.c_[np.cos(s), np.sin(s), np.where(s > np.pi, 0.6 * (s - np.pi) / (0.5 * np.pi), 0.0)]
    # the end's winding: round the lap's strand on the loop's right side, starting
    # above it; this sense makes one turn a knot (the other undoes the loop's crossing)
    w = np.linspace(-0.5 * np.pi + 0.5, 0.5 * np.pi - 0.3, 2 * n * turns + 1)
    phi = 0.5 * np.pi - 2.0 * np.pi * turns * (w - w[0]) / (w[-1] - w[0])
    wind = np.c_[(1.0 + 0.3 * np.cos(phi)) * np.cos(w), (1.0 + 0.3 * np.cos(phi)) * np.sin(w)]
    wind = np.c_[wind, 0.3 * np.sin(phi)]
    over = lap[-1] + (wind[0] - lap[-1]) * np.linspace(0.0, 1.0, 10)[1:-1, None]
    end = wind[-1]
    leave = np.array([[end[0], end[1], 1.5], [3.0, 0.0, 1.5], [6.0, 0.0, 0.0]])
    pts = np.vstack([standing, lap, over, wind, leave])
    if not right:
        pts[:, 2] *= -1.0
    return pts


def surgeons_knot(*, right_first: bool = True, mirrored: bool = True) -> NDArray[np.float64]:
    """Surgeon's knot: a double overhand, then a single throw along the thread.

    Args:
        right_first: handedness of the double throw.
        mirrored: the second throw is the first's mirror image (a surgeon's knot);
            ``False`` gives both throws one hand (the surgeon's granny).
    """
    second_right = not right_first if mirrored else right_first
    return connected_sum(overhand(2, right=right_first), overhand(1, right=second_right))


def wobbly_unknot(n: int = 120, *, turns: int = 6) -> NDArray[np.float64]:
    """An unknot whose projections have many crossings.

    The curve runs along +x inside a coil of radius 0.4, then returns along
    -x on a coil of radius 1 wound the other way: a thread inside a spring,
    which can be pulled out, so unknotted, but seen from most directions it
    crosses itself dozens of times.
    """
    half = n // 2
    t = np.linspace(0.0, 1.0, half)
    inner = np.c_[6.0 * t, 0.4 * np.cos(2 * np.pi * turns * t), 0.4 * np.sin(2 * np.pi * turns * t)]
    back = t[::-1]
    outer = np.c_[
        6.0 * back + 0.3,
        1.0 * np.cos(-2 * np.pi * (turns + 1) * back),
        1.0 * np.sin(-2 * np.pi * (turns + 1) * back) + 0.05,
    ]
    return np.vstack([inner, outer])


def half_hitches(n: int = 120, *, turns: float = 2.0) -> NDArray[np.float64]:
    """A straight post with the other strand wrapped around it (thesis Fig. 7.4).

    Strand 1 runs straight along +x through the knot region at the origin
    (radius about 1), leaves it, makes a stitch loop below (z < 0) and comes
    back to wrap ``turns`` times around the post (radius 0.6) before leaving
    upwards.
    """
    q = max(n // 4, 8)
    post = np.c_[np.linspace(-4.0, 3.0, q), np.zeros(q), np.zeros(q)]
    s = np.linspace(0.0, np.pi, q)
    loop = np.c_[1.9 + 1.1 * np.cos(s), np.full(q, 0.6), -2.5 * np.sin(s)]
    w = np.linspace(0.0, 1.0, 2 * q)[1:]
    ang = 2.0 * np.pi * turns * w
    wrap = np.c_[0.8 - 1.6 * w, 0.6 * np.cos(ang), -0.6 * np.sin(ang)]
    rise = np.linspace(0.0, 4.0, q)[1:]
    exit_leg = np.c_[np.full(len(rise), wrap[-1, 0]), np.full(len(rise), wrap[-1, 1]), rise]
    return np.vstack([post, loop[1:], wrap, exit_leg])
