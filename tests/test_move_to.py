"""move-to's per-tick commands against a hand-written quintic (no physics)."""

from __future__ import annotations

import numpy as np

from skills.move_to import MoveTo
from suture_engine.robot import endobot
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    CommandMode,
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    ToolState,
)

ROBOT = "endobot_1"


def _obs(t: float, q: np.ndarray) -> Observation:
    ro = RobotObservation(q=q, qd=np.zeros(4), base_wrench=np.zeros(6), tool=ToolState())
    return Observation(tick=round(t * 1e3), t=t, robots={ROBOT: ro}, scene=SceneGeometry())


def test_commands_follow_the_quintic_to_the_target_and_are_frozen() -> None:
    q0 = np.array([0.1, -0.1, 0.2, 0.1])
    target = (0.01, 0.02, 0.11)
    skill = MoveTo({"robot": "arm", "target": target, "speed": 0.05})
    ctx = SkillContext(step="s", roles={"arm": ROBOT}, dt=1e-3, start=_obs(0.0, q0), params={})
    skill.start(ctx)
    q1 = np.array(skill._traj.q1)
    duration = skill._traj.duration
    q = q0
    for k in range(round(duration * 1e3) + 5):
        t = k * 1e-3
        res = skill.step(ctx, _obs(t, q))
        cmd = res.command.robots[ROBOT]
        assert cmd.mode is CommandMode.POSITION
        assert cmd.q is not None and cmd.qd is not None
        assert not cmd.q.flags.writeable and not cmd.qd.flags.writeable
        tau = min(t / duration, 1.0)
        s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
        ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
        np.testing.assert_allclose(cmd.q, q0 + s * (q1 - q0), atol=1e-12)
        np.testing.assert_allclose(cmd.qd, ds * (q1 - q0), atol=1e-10)
        q = np.array(cmd.q)  # perfect tracking
        if res.status is not SkillStatus.RUNNING:
            break
    assert res.status is SkillStatus.SUCCESS
    np.testing.assert_allclose(endobot.forward_kinematics(q).position, target, atol=1e-9)
