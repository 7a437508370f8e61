"""The tissue's puncture model: a needle driven through the pad makes the channel along its
path and drags the thread into it; pulling it through costs the channel's friction (4.5),
not a collision with the pad."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from backends.pybullet.suture import Suture, SutureParams, configure_physics, straight_path
from backends.pybullet.tissue import CLEAR_DEPTH, WOUND_GAP, Tissue, TissueError
from backends.pybullet.tools import Stitcher

DOWN = (1.0, 0.0, 0.0, 0.0)  # rotation by pi about x: the tip's z points down
JAW = np.array([-4e-3, 0.0, -3e-3])  # jaw 0 from the tip, world frame, with DOWN


def _segment_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    out = []
    for x in points:
        best = np.inf
        for a, b in itertools.pairwise(line):
            u = b - a
            t = min(max(float((x - a) @ u) / float(u @ u), 0.0), 1.0)
            best = min(best, float(np.linalg.norm(a + t * u - x)))
        out.append(best)
    return np.array(out)


def _jaw_path(depth: float) -> list[np.ndarray]:
    """Where jaw 0 (the needle's swaged end) goes, one point per millisecond: down onto the
    entry point (0, -4, 0) mm, along a sin-shaped arc ``depth`` deep to the exit (0, 4, 0)
    mm, then 25 mm straight up, all at 10 mm/s."""
    speed, dt = 0.01, 1e-3
    pts: list[np.ndarray] = []

    def line(a: np.ndarray, b: np.ndarray) -> None:
        n = max(1, round(float(np.linalg.norm(b - a)) / (speed * dt)))
        pts.extend(a + (b - a) * k / n for k in range(1, n + 1))

    entry, exit_ = np.array([0.0, -4e-3, 0.0]), np.array([0.0, 4e-3, 0.0])
    line(entry + np.array([0.0, 0.0, 8e-3]), entry)
    arc_n = round(0.010 / (speed * dt))
    for k in range(1, arc_n + 1):
        s = k / arc_n
        pts.append(entry + s * (exit_ - entry) - [0, 0, depth * math.sin(math.pi * s)])
    line(exit_, exit_ + np.array([0.0, 0.0, 0.025]))
    return pts


@pytest.fixture(scope="module")
def stitch() -> dict[str, object]:
    """Drive a stitcher so that its needle bites through the pad, and record what happens."""
    import pybullet as p

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        tissue = Tissue.create(
            c, (0.0, 0.0, 0.0), (0.0, -4e-3, 0.0), (0.0, 4e-3, 0.0), size=(0.08, 0.08, 0.01)
        )
        path = _jaw_path(2e-3)
        start_jaw = path[0] - [0, 0, 1e-3]
        sut = Suture.create(
            c,
            straight_path(tuple(start_jaw - [0.3, 0, 0]), (1.0, 0.0, 0.0), 0.3),
            SutureParams(),
        )
        tool = Stitcher.create(
            c, "s", tuple(start_jaw - JAW), DOWN, needle_body=sut.needle_body, place_needle=False
        )
        tissue.track(sut)
        before_threaded = tissue.suture
        forces, inside, heights = [], [], []
        for k, jaw in enumerate(path):
            tool.set_pose(tuple(jaw - JAW), DOWN)
            tool.step()
            sut.pre_step()
            tissue.pre_step()
            p.stepSimulation(physicsClientId=c)
            forces.append(float(np.linalg.norm(p.getConstraintState(tool.drive, c)[:3])))
            inside.append(len(tissue.inside))
            heights.append(float(sut.centerline()[-1][2]))
            if k == 1300:  # half way through the bite
                mid_channel = tissue.channel.copy()
        return {
            "tissue": tissue,
            "before_threaded": before_threaded,
            "forces": np.array(forces),
            "inside": np.array(inside),
            "line": sut.centerline(),
            "mid_channel": mid_channel,
            "stretch": sut.stretch(),
            "n_path": len(path),
        }
    finally:
        p.disconnect(physicsClientId=c)


def test_needle_punctures_at_the_entry_and_the_channel_is_its_path(stitch) -> None:  # type: ignore[no-untyped-def]
    tissue = stitch["tissue"]
    assert stitch["before_threaded"] is None  # nothing captured before the puncture
    assert tissue.punctured and tissue.exited
    # The channel starts and ends where the swaged end crossed the surface, on it.
    assert np.allclose(tissue.entry, [0.0, -4e-3, 0.0], atol=0.3e-3)
    assert np.allclose(tissue.exit, [0.0, 4e-3, 0.0], atol=0.3e-3)
    channel = tissue.channel
    assert abs(channel[0][2]) < 1e-9 and abs(channel[-1][2]) < 1e-9
    # ... and follows the bite, 2 mm deep at mid-span (hand-built arc of _jaw_path).
    assert channel[:, 2].min() == pytest.approx(-2e-3, abs=0.2e-3)
    # Half way through the bite the channel grew only to where the needle was, mid-span.
    assert abs(stitch["mid_channel"][-1][1]) < 1e-3
    assert stitch["mid_channel"][-1][2] == pytest.approx(-2e-3, abs=0.3e-3)


def test_thread_is_dragged_through_the_channel_and_held_by_it(stitch) -> None:  # type: ignore[no-untyped-def]
    tissue = stitch["tissue"]
    line = stitch["line"]
    # The thread now runs through the whole channel (its 1.8 mm thick capsules within
    # 1 mm of every channel point) and out of the exit up to the needle.
    assert _segment_distance(tissue.channel, line).max() < 1e-3
    assert line[-1][2] > 0.02
    assert stitch["inside"][-500:].min() >= 1
    assert stitch["stretch"] < 0.03


def test_pulling_through_costs_the_channel_friction_not_a_collision(stitch) -> None:  # type: ignore[no-untyped-def]
    """The drive force during the bite and the pull stays near the channel's F_s = 0.3 N
    (4.5) plus the viscous F_v v = 0.02 N: the pad does not block the needle or the tool."""
    forces = stitch["forces"]
    bite = forces[800:1800]  # the needle inside the tissue
    pull = forces[-1500:]  # the thread sliding through the channel
    assert bite.max() < 1.0
    assert pull.max() < 1.0
    # The friction is felt while the thread slides: the mean pull is near F_s + F_v v.
    assert np.mean(pull[-800:]) == pytest.approx(0.32, abs=0.15)


def test_snag_adds_its_friction_while_it_lasts() -> None:
    """Drag a threaded suture through the channel at 10 mm/s; a 0.5 N snag for 0.4 s raises
    the grip force by about 0.5 N while it lasts (F_s + 0.5 N, (4.5))."""
    import pybullet as p

    from backends.pybullet.tools import Grasper

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        tissue = Tissue.create(
            c,
            (0.0, 0.0, 0.0),
            (-0.015, 0.0, 0.0),
            (0.015, 0.0, 0.0),
            depth=0.005,
            size=(0.12, 0.04, 0.01),
        )
        for body in tissue.bodies:
            p.changeDynamics(body, -1, lateralFriction=0.0, physicsClientId=c)
        h = 0.0015
        path = np.vstack(
            [[-0.2, 0.0, h], [-0.016, 0.0, h], tissue.channel, [0.016, 0.0, h], [0.2, 0.0, h]]
        )
        sut = Suture.create(c, path, SutureParams(needle=False))
        tissue.thread(sut)
        end = sut.centerline()[-1]
        grasper = Grasper.create(c, "g", (end[0], end[1], end[2]), suture=sut, hook=False)
        grasper.close()
        forces = []
        for k in range(1400):
            if k > 200:
                grasper.set_pose((end[0] + 0.01 * (k - 200) / 1000, end[1], end[2]))
            if k == 900:
                tissue.snag(0.5, 0.4)
            grasper.step()
            sut.pre_step()
            tissue.pre_step()
            p.stepSimulation(physicsClientId=c)
            forces.append(grasper.grip_force())
        before = float(np.mean(forces[650:900]))
        during = float(np.mean(forces[1050:1300]))
        assert grasper.holding and tissue.inside
        assert during - before == pytest.approx(0.5, abs=0.15)
    finally:
        p.disconnect(physicsClientId=c)


def _tighten_loop(k_hole: float, pull: float = 1.0) -> tuple[float, float]:
    """A made stitch (8 mm bite, tail 30 mm out of the entry, the long strand out of the exit)
    whose two ends are pulled, force-limited, back over the wound towards -y, the tail
    harder (``pull`` [N]) than the long end (0.6 ``pull``), as a tightening stitch loop
    does: the thread slides through the channel. Returns the largest distance [m] from a
    puncture hole to the thread after the holes' hold is taken up (0.5 s on), and the
    lowest point of the thread at the end (z [m])."""
    import pybullet as p

    from backends.pybullet.scene import channel_depth

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        entry, exit_ = np.array([0.0, -4e-3, 0.0]), np.array([0.0, 4e-3, 0.0])
        tissue = Tissue.create(
            c, (0.0, 0.0, 0.0), tuple(entry), tuple(exit_), depth=channel_depth(8e-3),
            size=(0.04, 0.04, 0.01), k_hole=k_hole,
        )  # fmt: skip
        params = SutureParams(length=0.12, n_segments=40, needle=False)
        lift = np.array([0.0, 0.0, params.collision_radius + 0.5e-3])
        seg = params.length / params.n_segments
        path = np.vstack(
            [
                entry + lift + [0.0, -0.030, 0.0],
                entry + lift + [0.0, -seg, 0.0],
                tissue.channel,
                exit_ + lift + [0.0, seg, 0.0],
                exit_ + lift + [0.0, 0.02, 0.0],
                exit_ + lift + [0.0, 0.02, 0.06],
            ]
        )
        sut = Suture.create(c, path, params)
        tissue.thread(sut)
        tissue.punctured = tissue.exited = True  # the stitch is made
        ends = (0, len(sut.bodies) - 1)
        goals = (np.array([0.03, -0.03, 0.004]), np.array([-0.03, -0.02, 0.004]))
        hands = []
        for i in ends:
            x, _ = p.getBasePositionAndOrientation(sut.bodies[i], physicsClientId=c)
            hands.append(
                p.createConstraint(
                    sut.bodies[i], -1, -1, -1, p.JOINT_POINT2POINT, [0, 0, 0], [0, 0, 0], x,
                    physicsClientId=c,
                )
            )  # fmt: skip
        worst = 0.0
        for k in range(3000):
            s = min(1.0, k / 2500)
            for cons, i, goal, force in zip(hands, ends, goals, (pull, 0.6 * pull), strict=True):
                start = path[0] if i == 0 else path[-1]
                p.changeConstraint(
                    cons, jointChildPivot=(start + s * (goal - start)).tolist(),
                    maxForce=force, physicsClientId=c,
                )  # fmt: skip
            sut.pre_step()
            tissue.pre_step()
            p.stepSimulation(physicsClientId=c)
            if k >= 500 and k % 50 == 0:
                line = sut.centerline()
                worst = max(worst, float(_segment_distance(np.stack([entry, exit_]), line).max()))
        return worst, float(sut.centerline()[:, 2].min())
    finally:
        p.disconnect(physicsClientId=c)


# slow: two thread runs, 10 s of the CI suite under load; `pytest -m slow` runs it
@pytest.mark.slow
def test_the_puncture_holes_hold_a_thread_pulled_back_over_the_wound() -> None:
    """The holes are eyelets: a stitch loop tightened back over the wound still passes
    through both of them (measured 0.5 mm at a 2 N pull) and under the surface. Without
    them (k_hole 0, the earlier model) the thread wanders 1.5 mm off the holes under the
    same pull; in algorithm 3 it was drawn out of the tissue altogether."""
    held, lowest = _tighten_loop(k_hole=1500.0, pull=2.0)
    assert held < 0.8e-3
    assert lowest < 0.0
    loose, _ = _tighten_loop(k_hole=0.0, pull=2.0)
    assert loose > 1.2e-3


def test_the_tissue_cross_product_has_numpy_s_bits() -> None:
    """The guidance's cross product is ``np.cross`` bit for bit (rows and single vectors,
    magnitudes from 1e-6 to 1e2), so replacing it changed no trace."""
    from backends.pybullet.tissue import _cross

    rng = np.random.default_rng(0)
    a = rng.normal(size=(500, 3)) * 10 ** rng.uniform(-6, 2, size=(500, 1))
    b = rng.normal(size=(500, 3))
    assert np.array_equal(_cross(a, b), np.cross(a, b))
    assert all(np.array_equal(_cross(a[i], b[i]), np.cross(a[i], b[i])) for i in range(50))


def _numpy_hole_pull(hole, near, pos, axes, h, gain):  # type: ignore[no-untyped-def]
    """The eyelet pull as 3-vector numpy expressions (the form the float path replaced)."""
    seg = 2 * h
    k0 = int(near / seg)
    best, where, cap_i, at_t = np.inf, None, -1, 0.5
    for i in range(max(0, k0 - 2), min(len(pos), k0 + 3)):
        if np.isnan(pos[i, 0]):
            continue
        a0 = pos[i] - h * axes[i]
        tt = min(max(float((hole - a0) @ axes[i]) / seg, 0.0), 1.0)
        q = a0 + seg * tt * axes[i]
        d = float(np.linalg.norm(hole - q))
        if d < best:
            best, where, cap_i, at_t = d, q, i, tt
    if where is None:
        return None
    err = hole - where
    other = cap_i + (1 if at_t > 0.5 else -1)
    tangent = axes[cap_i].copy()
    if 0 <= other < len(pos) and not np.isnan(axes[other, 0]):
        tangent += 2.0 * abs(at_t - 0.5) * axes[other]
        tangent /= np.linalg.norm(tangent)
    err = err - tangent * float(err @ tangent)
    f = gain * err
    return cap_i, f, np.cross(where - pos[cap_i], f)


def _random_thread(rng: np.random.Generator, n: int = 12, seg: float = 3.5e-3):  # type: ignore[no-untyped-def]
    """A wiggly chain of capsule centres and unit axes, some outside the window (NaN)."""
    axes = rng.normal(size=(n, 3)) + np.array([1.0, 0.0, 0.0])
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    pos = np.cumsum(axes * seg, axis=0) + rng.normal(scale=1e-4, size=(n, 3))
    hidden = rng.random(n) < 0.2
    pos[hidden] = np.nan
    axes[hidden] = np.nan
    pos_t = [None if np.isnan(p[0]) else tuple(p.tolist()) for p in pos]
    axis_t = [None if np.isnan(a[0]) else tuple(a.tolist()) for a in axes]
    return pos, axes, pos_t, axis_t


def test_the_eyelet_pull_in_floats_has_the_numpy_expressions_bits() -> None:
    """The hole's pull, force and torque, computed in Python floats, equal the 3-vector
    numpy expressions they replaced bit for bit (random threads, holes and gains), so the
    change kept every trace byte (checked too on whole runs: the same trace files)."""
    from backends.pybullet.tissue import _hole_pull

    rng = np.random.default_rng(3)
    seg = 3.5e-3
    compared = 0
    for _ in range(400):
        pos, axes, pos_t, axis_t = _random_thread(rng, seg=seg)
        near = float(rng.uniform(0.0, 12 * seg))
        hole = pos[min(int(near / seg), 11)] + rng.normal(scale=1e-3, size=3)
        if np.isnan(hole[0]):
            hole = rng.normal(scale=1e-2, size=3)
        gain = float(rng.uniform(100.0, 2000.0))
        want = _numpy_hole_pull(hole, near, pos, axes, seg / 2, gain)
        got = _hole_pull(hole.tolist(), near, pos_t, axis_t, seg / 2, gain)
        assert (want is None) == (got is None)
        if want is None or got is None:
            continue
        assert got[0] == want[0]
        assert np.array_equal(np.array(got[1]), want[1])
        assert np.array_equal(np.array(got[2]), want[2])
        compared += 1
    assert compared > 300


def test_the_guided_force_in_floats_has_the_numpy_expressions_bits() -> None:
    """A capsule's guided force (pull, lateral damping, viscous friction) in floats equals
    ``pull - c_lat * (v - a (v . a)) - (c_visc * l_dot) * t`` in numpy, bit for bit."""
    from backends.pybullet.tissue import _guided_force

    rng = np.random.default_rng(4)
    for _ in range(2000):
        pull = rng.normal(size=3) * 10 ** rng.uniform(-4, 1)
        v = rng.normal(size=3) * 10 ** rng.uniform(-5, -1)
        a = rng.normal(size=3)
        a /= np.linalg.norm(a)
        t = rng.normal(size=3)
        t /= np.linalg.norm(t)
        c_lat, c_visc, l_dot = rng.uniform(0.0, 2.0), rng.uniform(0.0, 0.5), rng.normal()
        axial = np.float64(l_dot)
        v_perp = v - a * float(v @ a)
        want = pull - c_lat * v_perp - c_visc * axial * t
        got = _guided_force(
            pull.tolist(),
            tuple(v.tolist()),
            tuple(a.tolist()),
            c_lat,
            c_visc * l_dot,
            tuple(t.tolist()),
        )
        assert np.array_equal(np.array(got), want)
        outside = _guided_force(
            pull.tolist(), tuple(v.tolist()), tuple(a.tolist()), c_lat, 0.0, None
        )
        assert np.array_equal(np.array(outside), pull - c_lat * v_perp)


def test_the_entry_arc_length_in_floats_has_the_numpy_expressions_bits() -> None:
    """Following the thread's arc length at the entry point in floats picks the same
    capsule and the same arc length [m] as the numpy expressions did."""
    rng = np.random.default_rng(5)
    seg = 3.5e-3
    h = seg / 2
    for _ in range(300):
        pos, axes, pos_t, axis_t = _random_thread(rng, seg=seg)
        tissue = Tissue.__new__(Tissue)
        tissue._sigma = None if rng.random() < 0.5 else float(rng.uniform(0.0, 11 * seg))
        entry = rng.normal(scale=1e-2, size=3) + np.array([0.02, 0.0, 0.0])
        tissue.channel = np.array([entry, entry + 1e-3])
        start_sigma = tissue._sigma
        tissue._update_sigma(pos_t, axis_t, h)
        # the numpy form
        if start_sigma is None:
            window = range(len(pos))
        else:
            k = int(start_sigma / seg)
            window = range(max(0, k - 1), min(len(pos), k + 2))
        best, sigma = np.inf, 0.0
        for i in window:
            if np.isnan(pos[i, 0]):
                continue
            a = pos[i] - h * axes[i]
            t = min(max(float((entry - a) @ axes[i]) / (2 * h), 0.0), 1.0)
            d = float(np.linalg.norm(pos[i] + (2 * t - 1) * h * axes[i] - entry))
            if d < best:
                best, sigma = d, (i + t) * seg
        assert tissue._sigma == sigma


def _pull_along_the_wound(gap: float, depth: float | None = None) -> tuple[float, float]:
    """A 60 mm thread of eight capsules lies along the wound on the pad. For 0.3 s each
    capsule is pressed down with 0.5 N (a knot drawn down onto the wound); then the press
    stops and a 0.2 N pull along the wound draws its end for 0.5 s. Returns how far the
    end went along the wound [m] and the largest joint tension read while pulled [N]."""
    import pybullet as p

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        tissue = Tissue.create(
            c, (0.0, 0.0, 0.0), (0.0, -4e-3, 0.0), (0.0, 4e-3, 0.0),
            size=(0.08, 0.08, 0.01), wound_gap=gap, wound_depth=depth,
        )  # fmt: skip
        sut = Suture.create(
            c,
            straight_path((-0.03, 0.0, 1e-3), (1.0, 0.0, 0.0), 0.06),
            SutureParams(length=0.06, n_segments=8, needle=False),
        )
        start, peak = 0.0, 0.0
        for k in range(800):
            sut.pre_step()
            tissue.pre_step()
            pressed = k < 300
            if k == 300:
                start = float(sut.centerline()[-1][0])
            for body in sut.bodies if pressed else sut.bodies[-1:]:
                at, _ = p.getBasePositionAndOrientation(body, physicsClientId=c)
                force = [0.0, 0.0, -PRESS] if pressed else [PULL, 0.0, 0.0]
                p.applyExternalForce(body, -1, force, at, p.WORLD_FRAME, physicsClientId=c)
            p.stepSimulation(physicsClientId=c)
            sut.stepped()
            if not pressed:
                peak = max(peak, float(sut.tensions().max()))
        return float(sut.centerline()[-1][0]) - start, peak
    finally:
        p.disconnect(physicsClientId=c)


PRESS = 0.5
"""The press on each capsule in the wound tests [N]."""
PULL = 0.2
"""The pull on the thread's end in the wound tests [N]."""


@pytest.mark.parametrize(("gap", "depth"), [(0.0, None), (1e-3, 0.4e-3)])
def test_a_thread_pressed_onto_a_closed_wound_slides_along_it_under_its_pull(
    gap: float, depth: float | None
) -> None:
    """With the wound closed (its halves touching), or open only 0.4 mm deep above a
    floor, a thread pressed down onto it and let go slides along it under a small pull,
    and no joint reads more than the pull: Newton's law for a thread that nothing else
    holds along its length."""
    moved, peak = _pull_along_the_wound(gap, depth)
    assert moved > 0.05
    assert peak <= PULL * 1.001


@pytest.mark.xfail(
    strict=True,
    reason="known limit of the default 1 mm wound: the 1.8 mm capsules pressed into it are "
    "pinched between the pad's static halves, held, and read several newtons (docs/status.md)",
)
def test_a_thread_pressed_into_the_default_wound_slides_along_it_under_its_pull() -> None:
    moved, peak = _pull_along_the_wound(WOUND_GAP)
    assert moved > 0.05
    assert peak <= PULL * 1.001


@pytest.mark.parametrize(
    ("gap", "depth", "field"),
    [(-1e-3, None, "wound_gap"), (0.08, None, "wound_gap"), (1e-3, 0.0, "wound_depth"),
     (1e-3, 0.01, "wound_depth"),
     # the bites 4 mm either side of the wound: an opening wider than 8 mm leaves them in it
     (8.2e-3, None, "wound_gap.*inside its 8.2 mm opening")],
)  # fmt: skip
def test_a_wound_outside_the_pad_is_refused(gap: float, depth: float | None, field: str) -> None:
    import pybullet as p

    c = p.connect(p.DIRECT)
    try:
        with pytest.raises(TissueError, match=field):
            Tissue.create(
                c, (0.0, 0.0, 0.0), (0.0, -4e-3, 0.0), (0.0, 4e-3, 0.0),
                size=(0.08, 0.08, 0.01), wound_gap=gap, wound_depth=depth,
            )  # fmt: skip
    finally:
        p.disconnect(physicsClientId=c)


def _cut_the_channel(clear_depth: float | None) -> tuple[float, float, int]:
    """A 40 mm thread lies in a straight channel 2 mm under the surface. After 0.1 s the
    channel is cut to its first 14 mm (as when the thread slips through the stitch): the
    capsules past it leave the channel while still inside the pad. Returns the fastest
    capsule's speed [m/s] and the largest joint tension [N] in the 0.3 s after the cut, and
    how many capsules are left in the channel."""
    import pybullet as p

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        tissue = Tissue.create(
            c, (0.0, 0.0, 0.0), (0.0, -15e-3, 0.0), (0.0, 15e-3, 0.0), size=(0.06, 0.04, 0.01),
            clear_depth=clear_depth,
        )  # fmt: skip
        sut = Suture.create(
            c,
            straight_path((0.0, -0.02, -2e-3), (0.0, 1.0, 0.0), 0.04),
            SutureParams(length=0.04, n_segments=10, needle=False),
        )
        tissue.channel = np.array([(0.0, -0.02 + 1e-3 * k, -2e-3) for k in range(41)])
        tissue.thread(sut)
        peak, fastest = 0.0, 0.0
        for k in range(400):
            if k == 100:
                tissue.channel = tissue.channel[:15]
            sut.pre_step()
            tissue.pre_step()
            p.stepSimulation(physicsClientId=c)
            sut.stepped()
            if k >= 100:
                peak = max(peak, float(sut.tensions().max()))
                speeds = [np.linalg.norm(p.getBaseVelocity(b, physicsClientId=c)[0])
                          for b in sut.bodies]  # fmt: skip
                fastest = max(fastest, float(max(speeds)))
        return fastest, peak, len(tissue.inside)
    finally:
        p.disconnect(physicsClientId=c)


def test_a_capsule_that_leaves_the_channel_inside_the_pad_waits_to_come_out() -> None:
    """With the tissue's wait (``clear_depth``), the capsules cut out of the channel are
    not thrown out by the contacts they would get back inside the pad."""
    fastest, peak, inside = _cut_the_channel(CLEAR_DEPTH)
    assert inside == 4  # the cut took effect: 14 mm of 4 mm capsules
    assert fastest < 0.05
    assert peak < 0.05


@pytest.mark.xfail(
    strict=True,
    reason="known limit of the default (no wait): a capsule that leaves the channel inside "
    "the pad gets its contacts back there and is thrown out, 1.4 m/s (docs/status.md)",
)
def test_by_default_a_capsule_that_leaves_the_channel_inside_the_pad_is_not_thrown() -> None:
    fastest, peak, _ = _cut_the_channel(None)
    assert fastest < 0.05
    assert peak < 0.05


def test_a_negative_clear_depth_is_refused() -> None:
    import pybullet as p

    c = p.connect(p.DIRECT)
    try:
        with pytest.raises(TissueError, match="clear_depth"):
            Tissue.create(
                c, (0.0, 0.0, 0.0), (0.0, -4e-3, 0.0), (0.0, 4e-3, 0.0), clear_depth=-1e-4
            )
    finally:
        p.disconnect(physicsClientId=c)
