"""``grasp``: close a grasper on the suture tail, the suture, or the needle (4.4)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Duration, Force, Length, Position

__all__ = ["Grasp", "GraspParams"]


class GraspParams(SkillParams):
    """Parameters of ``grasp``."""

    robot: RoleRef
    """The role of the grasping robot."""
    what: Literal["suture-tail", "suture", "needle", "tissue"] = "suture-tail"
    """What to grasp. The suture tail is found from the stitch just made
    (algorithm 1 step 2): the skill never measures the suture itself."""
    target: PointRef | Position | None = None
    """Where to grasp: a tissue point or (x, y, z) in the world frame [m];
    ``None`` grasps where the tool is."""
    offset: Position = (0.0, 0.0, 0.0)
    """Added to the target, world frame [m]."""
    force: Force = Field(default=2.0, gt=0.0, le=20.0)
    """Grip force [N]."""
    tolerance: Length | None = Field(default=None, gt=0.0, le=5e-3)
    """Tip position tolerance at the goal [m]; ``None`` uses the skill's
    :attr:`TOLERANCE`. A looser one suits a backend whose position control leaves
    a steady error (e.g. heavier mounted tools)."""
    dwell: Duration = Field(default=0.0, ge=0.0, le=2.0)
    """How long the tip is held at the goal after the jaw reports closed [s]. A
    pneumatic jaw reports closed when its valve switches, before the jaws have travelled
    shut (0.1 s on the surgical backend's graspers); a move that starts at once can carry
    them off what they close on. 0 ends the skill as the jaw reports closed."""


class Grasp(Skill):
    """Move the open grasper's tip to the target in a straight line, then close it.

    The tip follows the straight segment from where it is to ``target + offset``
    (minimum-jerk timing at :attr:`SPEED`), with the jaw commanded open; then the
    jaw is commanded closed and the skill succeeds when the tool reports it
    closed, after holding the tip at the goal for ``dwell``. It fails when the path
    leaves the joint limits, when the tip is not within :attr:`TOLERANCE` of the goal
    :attr:`SETTLE_S` after the path, or when the jaw does not report closed within
    :attr:`CLOSE_S`. The grip force is not forwarded: the runtime's tool command
    carries open/closed only.
    """

    name: ClassVar[str] = "grasp"
    Params: ClassVar[type[SkillParams]] = GraspParams
    tools: ClassVar[tuple[str, ...] | None] = ("grasper", "hook-grasper", "bent-tip-grasper")

    SPEED: ClassVar[float] = 0.02
    """Peak tool-tip speed of the approach [m/s] (free space: ~90 mm in about 8 s)."""
    TOLERANCE: ClassVar[float] = 1e-3
    """Tip position tolerance at the goal [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after the path to reach the tolerance [s]."""
    CLOSE_S: ClassVar[float] = 0.5
    """Time for the jaw to report closed [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._path: Any = None
        self._goal: Any = None
        self._failure = ""
        self._t0 = 0.0
        self._t_close: float | None = None
        self._t_closed: float | None = None

    def goal(self, ctx: Any) -> Any:
        """The grasp point in the world frame [m]."""
        import numpy as np

        from skills.tool_path import tip_world

        p = self.params
        assert isinstance(p, GraspParams)
        if p.target is None:
            base = tip_world(ctx.start.robots[self._robot].q, self._base)
        elif isinstance(p.target, str):
            points = ctx.scene.tissue.points if ctx.scene is not None else {}
            if p.target not in points:
                raise KeyError(f"no tissue point named {p.target!r}; known: {sorted(points)}")
            base = np.array(points[p.target], dtype=float)
        else:
            base = np.array(p.target, dtype=float)
        return np.asarray(base, dtype=float) + np.array(p.offset, dtype=float)

    def start(self, ctx: Any) -> None:
        """Plan the straight approach to the grasp point.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.tool_path import ToolPath, duration_for, ik_world, joint_box, tip_world

        p = self.params
        assert isinstance(p, GraspParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        self._t0 = ctx.t0
        self._t_close = None
        self._t_closed = None
        q0 = np.array(ctx.start.robots[self._robot].q)
        a = tip_world(q0, self._base)
        self._goal = self.goal(ctx)
        b = self._goal
        roll = float(q0[2])
        self._path = ToolPath(
            lambda s: ik_world(a + s * (b - a), roll, self._base),
            duration_for(float(np.linalg.norm(b - a)), self.SPEED),
        )
        self._failure = self._path.first_violation(joint_box(ctx, self._robot))

    def step(self, ctx: Any, obs: Any) -> Any:
        """Approach with the jaw open, then close it; success once it reports closed.

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        import numpy as np

        from skills.tool_path import hold_command, tip_tolerance, tip_world
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
            ToolCommand,
        )

        if self._failure:
            q = obs.robots[self._robot].q
            return StepResult(hold_command(self._robot, q), SkillStatus.FAILURE, self._failure)
        t = obs.t - self._t0
        q, qd, done = self._path.sample(t)
        if self._t_close is None:
            tool = ToolCommand(jaw_closed=False)
            cmd = Command({self._robot: RobotCommand.position(q, qd, tool)})
            if not done:
                return StepResult(cmd)
            err = float(
                np.linalg.norm(tip_world(obs.robots[self._robot].q, self._base) - self._goal)
            )
            if err <= tip_tolerance(self.params, self.TOLERANCE):
                self._t_close = obs.t
            elif t >= self._path.duration + self.SETTLE_S:
                return StepResult(
                    cmd, SkillStatus.FAILURE, f"grasper tip {err * 1e3:.2f} mm from the grasp point"
                )
            else:
                return StepResult(cmd)
        cmd = Command({self._robot: RobotCommand.position(q, None, ToolCommand(jaw_closed=True))})
        if self._t_closed is None and obs.robots[self._robot].tool.jaw_closed:
            self._t_closed = obs.t
        if self._t_closed is not None:  # closed: hold the goal for the dwell, then done
            p = self.params
            assert isinstance(p, GraspParams)
            done = obs.t - self._t_closed >= p.dwell
            return StepResult(cmd, SkillStatus.SUCCESS if done else SkillStatus.RUNNING)
        if obs.t - self._t_close >= self.CLOSE_S:
            return StepResult(cmd, SkillStatus.FAILURE, "the jaw did not report closed")
        return StepResult(cmd)
