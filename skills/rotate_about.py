"""``rotate-about``: rotate a tool about an axis through the RCM point (algorithm 1 step 4).

The axis is OP: O the centre of the spherical joint (the robot's RCM), P a
point given in the world frame or named in the scene, or taken relative to
another robot's tool tip. Rotating the whole tool about an axis through O
keeps the tool through the RCM: the tip moves on a circle about OP (its
distance to the axis is constant and its motion orthogonal to the axis) and
the tool frame turns with it, R(theta) = Rot(OP, theta) R(0). The joints come
from the closed-form inverse kinematics (3.14-3.17), the roll q3 from the
turned tool frame (3.11).
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, AngularSpeed, Length, Position

__all__ = ["RotateAbout", "RotateAboutParams", "axis_rotation"]


class RotateAboutParams(SkillParams):
    """Parameters of ``rotate-about``."""

    robot: RoleRef
    """The role of the robot that rotates."""
    angle: Angle = Field(ge=-4 * 3.141592653589793, le=4 * 3.141592653589793)
    """Rotation angle about OP [rad]; the mirror image of a knot uses the opposite sign."""
    point: PointRef | Position | None = None
    """P, the second point of the axis: a tissue point or (x, y, z) in the world frame
    [m]; ``None`` uses the contact point left by the previous step."""
    relative_to: RoleRef | None = None
    """When set, ``point`` is an offset [m] from that robot's tool tip."""
    speed: AngularSpeed = Field(default=0.5, gt=0.0, le=5.0)
    """Angular speed [rad/s]."""
    tolerance: Length | None = Field(default=None, gt=0.0, le=5e-3)
    """Tip position tolerance at the goal [m]; ``None`` uses the skill's
    :attr:`TOLERANCE`. A looser one suits a backend whose position control leaves
    a steady error (e.g. heavier mounted tools)."""


def axis_rotation(axis: Any, angle: float) -> Any:
    """Rotation matrix of ``angle`` [rad] about the unit ``axis`` (Rodrigues' formula)."""
    import numpy as np

    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    kx = np.array(((0.0, -k[2], k[1]), (k[2], 0.0, -k[0]), (-k[1], k[0], 0.0)))
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


class RotateAbout(Skill):
    """Rotate the tool by ``angle`` [rad] about the axis OP through the RCM point O.

    With ``point`` unset, P is the tool tip at the start (the contact point the
    previous step left). The rotation follows a minimum-jerk profile whose peak
    rate is ``speed``. Fails when the path leaves the joint limits, or when the
    tip is not within :attr:`TOLERANCE` [m] of the goal :attr:`SETTLE_S` [s]
    after the path.
    """

    name: ClassVar[str] = "rotate-about"
    Params: ClassVar[type[SkillParams]] = RotateAboutParams
    tools: ClassVar[tuple[str, ...] | None] = None

    TOLERANCE: ClassVar[float] = 1e-3
    """Tip position tolerance at the goal [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after the path to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._path: Any = None
        self._failure = ""
        self._t0 = 0.0
        self.axis_point: Any = None
        self.axis: Any = None
        self._goal: Any = None
        self._thetas: Any = [0.0]
        self._rolls: Any = [0.0]

    def _point_world(self, ctx: Any) -> Any:
        import numpy as np

        from skills.tool_path import tip_world

        p = self.params
        assert isinstance(p, RotateAboutParams)
        if p.point is None:
            return tip_world(ctx.start.robots[self._robot].q, self._base)
        if isinstance(p.point, str):
            points = ctx.scene.tissue.points if ctx.scene is not None else {}
            if p.point not in points:
                raise KeyError(f"no tissue point named {p.point!r}; known: {sorted(points)}")
            pt = np.array(points[p.point], dtype=float)
        else:
            pt = np.array(p.point, dtype=float)
        if p.relative_to is not None:
            other = ctx.robot(p.relative_to)
            pt = pt + tip_world(ctx.start.robots[other].q, ctx.base_poses.get(other))
        return pt

    def joints_at(self, theta: float, q0: Any, roll_reference: float | None = None) -> Any:
        """Joints [rad, m] after turning the tool by ``theta`` [rad] about OP (3.11, 3.14-3.17).

        Args:
            theta: rotation angle about OP [rad].
            q0: joints at theta = 0 [rad, m].
            roll_reference: the roll [rad] the result is unwrapped towards (continuity);
                default: interpolated from the table made by :meth:`start`.
        """
        import math

        import numpy as np

        from skills.tool_path import unwrap_roll
        from suture_engine.robot.kinematics import forward_kinematics, inverse_kinematics, rotation

        r_base = np.eye(3) if self._base is None else np.asarray(self._base[1]).reshape(3, 3)
        axis_b = r_base.T @ self.axis
        rot = axis_rotation(axis_b, theta)
        if roll_reference is None:
            roll_reference = float(np.interp(theta, self._thetas, self._rolls))
        tip_b = rot @ np.asarray(forward_kinematics(q0).position)
        r_goal = rot @ rotation(q0)
        q = inverse_kinematics(tip_b, 0.0)
        m = rotation(q).T @ r_goal  # Rz(q3), from R = Rx(q1) Ry(q2) Rz(q3) (3.11)
        q[2] = unwrap_roll(math.atan2(m[1, 0], m[0, 0]), roll_reference)
        return q

    def _roll_table(self, angle: float, q0: Any, samples: int = 720) -> None:
        """Unwrap the roll continuously along the rotation (a table of theta -> q3)."""
        import numpy as np

        thetas = np.linspace(0.0, angle, samples + 1)
        rolls = np.empty_like(thetas)
        ref = float(q0[2])
        for i, th in enumerate(thetas):
            ref = float(self.joints_at(float(th), q0, ref)[2])
            rolls[i] = ref
        if angle < 0:
            thetas, rolls = thetas[::-1], rolls[::-1]
        self._thetas, self._rolls = thetas, rolls

    def start(self, ctx: Any) -> None:
        """Find the axis OP and plan the rotation.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.tool_path import ToolPath, joint_box, tip_world

        p = self.params
        assert isinstance(p, RotateAboutParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        self._t0 = ctx.t0
        self._failure = ""
        q0 = np.array(ctx.start.robots[self._robot].q)
        origin = np.zeros(3) if self._base is None else np.asarray(self._base[0], dtype=float)
        self.axis_point = origin
        op = self._point_world(ctx) - origin
        if float(np.linalg.norm(op)) < 1e-6:
            self._failure = "P coincides with the RCM point O: the axis OP is undefined"
            self.axis = np.array((0.0, 0.0, 1.0))
        else:
            self.axis = op / np.linalg.norm(op)
        self._roll_table(p.angle, q0)
        duration = max(1.875 * abs(p.angle) / p.speed, 0.1)
        self._path = ToolPath(lambda s: self.joints_at(s * p.angle, q0), duration)
        if not self._failure:
            self._failure = self._path.first_violation(joint_box(ctx, self._robot))
        self._goal = tip_world(self._path.joints_at(1.0), self._base)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Track the rotation; success at the goal.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

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
        )

        if self._failure:
            q = obs.robots[self._robot].q
            return StepResult(hold_command(self._robot, q), SkillStatus.FAILURE, self._failure)
        t = obs.t - self._t0
        q, qd, done = self._path.sample(t)
        cmd = Command({self._robot: RobotCommand.position(q, qd)})
        if not done:
            return StepResult(cmd)
        err = float(np.linalg.norm(tip_world(obs.robots[self._robot].q, self._base) - self._goal))
        if err <= tip_tolerance(self.params, self.TOLERANCE):
            return StepResult(cmd, SkillStatus.SUCCESS)
        if t >= self._path.duration + self.SETTLE_S:
            return StepResult(
                cmd, SkillStatus.FAILURE, f"tool tip {err * 1e3:.2f} mm from the rotated pose"
            )
        return StepResult(cmd)
