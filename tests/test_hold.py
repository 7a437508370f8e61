"""hold: the captured pose every tick, success after the duration."""

from __future__ import annotations

import numpy as np

from skills.hold import Hold
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    CommandMode,
    Observation,
    RobotObservation,
    SceneGeometry,
    SkillStatus,
    ToolState,
)

ROBOT = "endobot_2"


def _obs(t: float, q: np.ndarray) -> Observation:
    ro = RobotObservation(q=q, qd=np.zeros(4), base_wrench=np.zeros(6), tool=ToolState())
    return Observation(tick=round(t * 1e3), t=t, robots={ROBOT: ro}, scene=SceneGeometry())


def test_hold_commands_the_captured_pose_until_the_duration() -> None:
    q0 = np.array([0.2, 0.1, -0.3, 0.09])
    skill = Hold({"robot": "arm", "duration": 0.01})
    ctx = SkillContext(step="s", roles={"arm": ROBOT}, dt=1e-3, start=_obs(0.0, q0), params={})
    skill.start(ctx)
    statuses = []
    for k in range(12):
        moved = q0 + 0.01 * k  # wherever the arm is, the set point stays q0
        res = skill.step(ctx, _obs(k * 1e-3, moved))
        cmd = res.command.robots[ROBOT]
        assert cmd.mode is CommandMode.POSITION and cmd.q is not None
        assert np.array_equal(cmd.q, q0) and not cmd.q.flags.writeable
        statuses.append(res.status)
    # Success at t >= duration - dt/2, i.e. from tick 10 on.
    assert statuses[:10] == [SkillStatus.RUNNING] * 10
    assert statuses[10] is SkillStatus.SUCCESS
