"""The two-grasper grip rig shared by the grip-limit tests (``test_tools.py``,
``test_backend_events.py``): a straight thread between two graspers' jaws, the near one
holding it mid-way with a grip limit, the far one (no limit) holding its last capsule."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from backends.pybullet.suture import Suture, SutureParams, configure_physics, straight_path
from backends.pybullet.tools import Grasper

SEGMENTS = 16
LENGTH = 0.12
"""The thread's length [m]."""
HELD = 8
"""The capsule the limited grasper holds (mid-thread, so it can slide past several)."""


@dataclass
class GripRig:
    client: int
    suture: Suture
    near: Grasper
    far: Grasper
    direction: np.ndarray
    """The thread's direction, from its start to the far jaws (unit)."""


def build_grip_rig(
    p: object,
    limit: float,
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0),
    held: int = HELD,
) -> GripRig:
    """Connect a headless PyBullet client and build the rig in it. ``limit`` is the near
    grasper's grip limit [N]; ``held`` the capsule it holds. The caller disconnects
    ``rig.client``."""
    c = p.connect(p.DIRECT)  # type: ignore[attr-defined]
    configure_physics(c)
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    params = SutureParams(length=LENGTH, n_segments=SEGMENTS, needle=False)
    suture = Suture.create(c, straight_path((0.0, 0.0, 0.05), tuple(d), LENGTH), params)
    line = suture.centerline()
    near = Grasper.create(
        c,
        "near",
        tuple((line[held] + line[held + 1]) / 2),
        suture=suture,
        hook=False,
        grip_limit=limit,
    )
    far = Grasper.create(c, "far", tuple((line[-2] + line[-1]) / 2), suture=suture, hook=False)
    near.grip(held)
    far.grip(SEGMENTS - 1)
    return GripRig(c, suture, near, far, d)
