"""``register``: touch the scene's calibration posts with the shaft, and correct the base.

The tool-to-tool and tool-to-tissue moves place a tool through its robot's declared base
pose, so a calibration error of the base moves every target by that error. This skill
measures it by touch (:mod:`suture_engine.robot.registration`). For each touch the robot
places its shaft beside a post of the scene (``posts``), ``behind`` its tool tip and
``clearance`` from the post's surface; then it brings the shaft onto the post at
``approach_speed`` until its base force/torque sensor feels the contact
(``contact_force`` along the motion, tared before the approach, as a guarded
``move-to``). The joints measured there give the model's distance between the shaft's
axis and the post's; the radii give the true one. After the last touch the robot goes
back to where it was.

A ``side`` touch crosses the post ``height`` above its foot, the shaft coming from the
post's ``side`` (+1: the side along z x (post - RCM); -1: the other). Its normal lies in
the horizontal plane, square to the shaft. A ``top`` touch passes the shaft over the
post's top and comes down onto it: its normal is the vertical's part square to the
shaft. Spread the touches (two posts seen from different directions, and a top) so that
their normals span space; the summary's ``registration_least_seen`` says how well they
did.

On success the interpreter adds the estimated displacement to the robot's declared base
position for the rest of the run (every later skill and invariant sees it); the summary's
metrics give it.

Moves between poses are checked against the posts before they start: a joint-space move
whose shaft would sweep through a post goes through a waypoint further out along the
touch's normal, and a plan that still meets a post fails the step before anything moves.
"""

from __future__ import annotations

import itertools
from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import RoleRef
from suture_engine.language.units import Force, Length, Speed

__all__ = ["Register", "RegisterParams", "TouchSpec"]

SHAFT_RADIUS = 2.5e-3
"""The instruments' shaft radius [m] (5 mm laparoscopic tools): ``shaft_radius``'s
default."""
SHAFT_BARE = 6e-3
"""How far behind the tool tip the shaft's cylinder starts [m] (the jaws are in front)."""
SHAFT_LENGTH = 0.3
"""The length of shaft behind the tool tip that the model counts [m]."""
SWEEP_MARGIN = 1.5e-3
"""The least planned gap between the shaft and a post while moving between poses [m]."""


class TouchSpec(SkillParams):
    """One touch of a post."""

    post: str
    """The post's name in the scene's ``posts``."""
    on: Literal["side", "top"] = "side"
    """Touch the post's side, or come down onto its top."""
    height: Length = Field(default=0.02, ge=0.0)
    """A side touch: how far above the post's foot the shaft crosses it [m]."""
    side: Literal[1, -1] = 1
    """A side touch: which side of the post the shaft comes from (module docstring)."""


class RegisterParams(SkillParams):
    """Parameters of ``register``."""

    robot: RoleRef
    """The role of the robot that registers its base."""
    touches: list[TouchSpec] = Field(min_length=1)
    """The touches, in order."""
    behind: Length = Field(default=0.03, gt=0.01, le=0.1)
    """How far behind the tool tip the shaft meets the post [m] (clear of the jaws)."""
    clearance: Length = Field(default=0.004, gt=0.0, le=0.02)
    """Gap between the shaft's surface and the post's when an approach starts [m]."""
    overtravel: Length = Field(default=0.004, gt=0.0, le=0.01)
    """How far past the model's contact an approach may go before it fails [m]."""
    speed: Speed = Field(default=0.015, gt=0.0, le=0.05)
    """Tool-tip speed between poses [m/s]."""
    approach_speed: Speed = Field(default=0.002, gt=0.0, le=0.01)
    """Tool-tip speed while the shaft approaches the post [m/s]."""
    contact_force: Force = Field(default=0.15, gt=0.0, le=2.0)
    """The force along the approach that means contact [N]."""
    shaft_radius: Length = Field(default=SHAFT_RADIUS, gt=0.0, le=0.01)
    """Where the shaft's surface touches, from its axis [m]: the instrument's radius, plus
    any contact margin (measured once by touching with a calibrated base)."""
    sigma: Length = Field(default=0.001, gt=0.0)
    """The prior spread of each component of the base's calibration error [m]."""
    noise: Length = Field(default=1e-4, gt=0.0)
    """The spread of one touch's measured gap [m]."""


def _unit(v: Any) -> Any:
    import numpy as np

    return v / np.linalg.norm(v)


class Register(Skill):
    """Register a robot's base by touching the scene's posts (see the module's docstring)."""

    name: ClassVar[str] = "register"
    Params: ClassVar[type[SkillParams]] = RegisterParams

    SETTLE_S: ClassVar[float] = 0.3
    """Time to settle after each move between poses [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robot = ""
        self._base: Any = None
        self._posts: dict[str, Any] = {}
        self._moves: list[tuple[str, int, Any, float]] = []
        self._index = 0
        self._traj: Any = None
        self._t0 = 0.0
        self._end = 0.0
        self._est: Any = None
        self._directions: list[Any] = []
        self._touches: list[Any] = []
        self._result: Any = None
        assert isinstance(self.params, RegisterParams)
        self._radius = float(self.params.shaft_radius)

    @classmethod
    def check(cls, params: SkillParams, scene: Any) -> list[Any]:
        """Every touched post must be one of the scene's ``posts``."""
        from suture_engine.validation.problem import Problem

        assert isinstance(params, RegisterParams)
        posts = getattr(scene, "posts", None) or {}
        problems = []
        for i, touch in enumerate(params.touches):
            if touch.post not in posts:
                known = ", ".join(sorted(posts)) or "none: the scene declares no posts"
                problems.append(
                    Problem(
                        "unknown-post",
                        f"no post named {touch.post!r} in the scene (posts: {known})",
                        path=f"touches[{i}].post",
                    )
                )
        return problems

    # ----------------------------------------------------------- geometry
    def _post_segment(self, name: str) -> tuple[Any, Any, float]:
        import numpy as np

        post = self._posts[name]
        foot = np.asarray(post.position, float)
        return foot, foot + np.array([0.0, 0.0, post.height]), float(post.radius)

    def _shaft(self, q: Any) -> tuple[Any, Any]:
        from suture_engine.robot.registration import shaft_segment
        from suture_engine.runtime.trajectory import tool_tip_world

        tip = tool_tip_world(q, self._base)
        return shaft_segment(self._base[0], tip, SHAFT_BARE, SHAFT_LENGTH)

    def _sweep_gap(self, q0: Any, q1: Any) -> float:
        """The least gap [m] between the shaft and any post along a joint-space move."""
        import numpy as np

        from suture_engine.robot.registration import segment_closest

        gap = np.inf
        for s in np.linspace(0.0, 1.0, 25):
            a, b = self._shaft(q0 + s * (q1 - q0))
            for name in self._posts:
                p0, p1, r = self._post_segment(name)
                d = segment_closest(a, b, p0, p1).distance
                gap = min(gap, d - r - self._radius)
        return float(gap)

    def _joints(self, point: Any, roll: float) -> Any:
        from suture_engine.robot.kinematics import inverse_kinematics
        from suture_engine.runtime.trajectory import world_to_base

        return inverse_kinematics(world_to_base(point, self._base), roll)

    def _touch_plan(self, spec: TouchSpec, roll: float) -> tuple[Any, Any, Any, Any]:
        """Joints where the approach starts and may end, a waypoint further out, and the
        approach's direction (world)."""
        import numpy as np

        p = self.params
        assert isinstance(p, RegisterParams)
        foot, top, r_post = self._post_segment(spec.post)
        rcm = np.asarray(self._base[0], float)
        z = np.array([0.0, 0.0, 1.0])
        if spec.on == "side":
            point = foot + spec.height * z
            normal = np.cross(z, point - rcm)
            if np.linalg.norm(normal) < 1e-9:
                raise ValueError(f"post {spec.post!r} stands under the RCM point")
            normal = spec.side * _unit(normal)
        else:
            point = top
            u = _unit(point - rcm)
            normal = _unit(z - (z @ u) * u)

        def tip(axis_point: Any) -> Any:
            return axis_point + p.behind * _unit(axis_point - rcm)

        contact = r_post + self._radius
        start = point + (contact + p.clearance) * normal
        end = point + (contact - p.overtravel) * normal
        out = point + (contact + p.clearance + 0.02) * normal
        q_start, q_end, q_out = (self._joints(tip(x), roll) for x in (start, end, out))
        return q_start, q_end, q_out, tip(end) - tip(start)

    def _lifted(self, q: Any) -> Any:
        """The joints with the tool tip raised above every post (the whole shaft then
        clears them), the roll kept."""
        import numpy as np

        from suture_engine.runtime.trajectory import tool_tip_world

        top = max(
            float(post.position[2]) + post.height + post.radius for post in self._posts.values()
        )
        tip = tool_tip_world(q, self._base)
        tip[2] = max(float(tip[2]), top + self._radius + 10e-3)
        return self._joints(np.asarray(tip), float(q[2]))

    def _route(self, q0: Any, q1: Any, vias: list[Any]) -> list[Any]:
        """Joint goals from q0 to q1 that keep clear of the posts: straight, else through
        one of the waypoints, else through them all in order, else with the tip raised
        above the posts at both ends."""
        candidates = [[q1]] + [[v, q1] for v in vias] + [[*vias, q1]]
        candidates.append([self._lifted(q0), self._lifted(q1), q1])
        for route in candidates:
            points = [q0, *route]
            if all(self._sweep_gap(a, b) >= SWEEP_MARGIN for a, b in itertools.pairwise(points)):
                return route
        raise ValueError(
            "the move between touches would sweep the shaft through a post; reorder the "
            "touches or move the posts"
        )

    # ----------------------------------------------------------- planning
    def start(self, ctx: Any) -> None:
        """Plan every move from the declared base and posts and the measured joints.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.

        Raises:
            ValueError: no declared base, a post under the RCM point, or a plan that
                meets a post.
            UnreachablePose: a touch the robot cannot reach.
        """
        import numpy as np

        p = self.params
        assert isinstance(p, RegisterParams)
        self._robot = ctx.robot(p.robot)
        self._base = ctx.base_poses.get(self._robot)
        if self._base is None:
            raise ValueError("register needs the robot's declared base pose")
        self._posts = dict(getattr(ctx.scene, "posts", None) or {})
        home = np.array(ctx.start.robots[self._robot].q, dtype=float)
        roll = float(home[2])
        moves: list[tuple[str, int, Any, float]] = []
        self._directions = []
        q = home
        last_out = None
        for k, spec in enumerate(p.touches):
            q_start, q_end, q_out, direction = self._touch_plan(spec, roll)
            self._directions.append(direction)
            vias = [q_out] if last_out is None else [last_out, q_out]
            for goal in self._route(q, q_start, vias):
                moves.append(("move", k, goal, p.speed))
            moves.append(("approach", k, q_end, p.approach_speed))
            moves.append(("move", k, q_start, p.speed))
            q, last_out = q_start, q_out
        for goal in self._route(q, home, [last_out]):
            moves.append(("move", -1, goal, p.speed))
        self._moves = moves
        self._touches = []
        self._result = None
        self._index = -1
        self._next(ctx, ctx.start)

    def _next(self, ctx: Any, obs: Any) -> None:
        """Start the next move from the measured joints."""
        import numpy as np

        from suture_engine.runtime.trajectory import MinJerk, min_jerk_duration, tool_tip_world

        self._index += 1
        if self._index >= len(self._moves):
            return
        kind, k, goal, speed = self._moves[self._index]
        q = np.array(obs.robots[self._robot].q, dtype=float)
        travel = float(
            np.linalg.norm(tool_tip_world(goal, self._base) - tool_tip_world(q, self._base))
        )
        duration = min_jerk_duration(travel, speed, minimum=0.1)
        self._traj = MinJerk(q, np.array(goal, dtype=float), duration)
        self._t0 = obs.t
        self._end = duration + (0.5 if kind == "approach" else self.SETTLE_S)
        self._est = None
        if kind == "approach":
            from suture_engine.suture.tension import mounted_estimator

            ro = obs.robots[self._robot]
            self._est, _ = mounted_estimator(
                self._base[1], self._directions[k], ro.base_wrench, ro.q, ctx.dt, 20.0
            )

    # ----------------------------------------------------------- running
    def step(self, ctx: Any, obs: Any) -> Any:
        """Run the moves; each approach ends at contact (a touch) or fails without one.

        Args:
            ctx: the skill context.
            obs: this tick's :class:`suture_engine.runtime.observation.Observation`.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        )

        t = obs.t - self._t0
        sample = self._traj(t)
        command = Command({self._robot: RobotCommand.trusted_position(sample.q, sample.qd)})
        if self._est is not None:
            ro = obs.robots[self._robot]
            force = self._est.update(ro.base_wrench, ro.q).tension
            p = self.params
            assert isinstance(p, RegisterParams)
            if force >= p.contact_force:
                self._touch(obs)
                hold = Command({self._robot: RobotCommand.trusted_position(sample.q, None)})
                self._next(ctx, obs)
                return StepResult(hold)
            if t >= self._end:
                k = self._moves[self._index][1]
                return StepResult(
                    command,
                    SkillStatus.FAILURE,
                    f"touch {k + 1} ({p.touches[k].post}): no contact within "
                    f"{p.overtravel * 1e3:.1f} mm past the model's (the base is off by "
                    "more, or something else holds the shaft)",
                )
            return StepResult(command)
        if t < self._end:
            return StepResult(command)
        self._next(ctx, obs)
        if self._index >= len(self._moves):
            self._finish()
            return StepResult(command, SkillStatus.SUCCESS)
        return StepResult(command)

    def _touch(self, obs: Any) -> None:
        """Record one contact from the joints measured now."""
        from suture_engine.robot.registration import Touch

        p = self.params
        assert isinstance(p, RegisterParams)
        k = self._moves[self._index][1]
        p0, p1, r_post = self._post_segment(p.touches[k].post)
        a, b = self._shaft(obs.robots[self._robot].q)
        self._touches.append(Touch((a, b), (p0, p1), r_post + self._radius))

    def _finish(self) -> None:
        from suture_engine.robot.registration import estimate_offset

        p = self.params
        assert isinstance(p, RegisterParams)
        self._result = estimate_offset(self._touches, p.sigma, p.noise)

    # ----------------------------------------------------------- results
    @property
    def base_corrections(self) -> dict[str, tuple[float, float, float]]:
        """Robot -> estimated displacement of its true base from the declared one [m],
        world frame; empty until the skill has succeeded."""
        if self._result is None:
            return {}
        x, y, z = (float(v) for v in self._result.offset)
        return {self._robot: (x, y, z)}

    def metrics(self) -> dict[str, float]:
        """The estimate [mm], the touches' residual [mm] and how well the least-seen
        direction was observed (the smallest singular value of the normals)."""
        if self._result is None:
            return {}
        out: dict[str, float] = {}
        for robot, offset in self.base_corrections.items():
            for axis, value in zip("xyz", offset, strict=True):
                out[f"registration_{robot}_{axis}_mm"] = round(value * 1e3, 4)
            out[f"registration_{robot}_residual_mm"] = round(self._result.residual * 1e3, 4)
            out[f"registration_{robot}_least_seen"] = round(float(self._result.observed[-1]), 4)
        return out
