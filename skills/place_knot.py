"""``place-knot``: slide the knot down to the tissue along its normal (4.5).

Both strand ends are pulled so that the knot slides (4.30-4.31) along the
suture-end trajectories (4.36-4.40) with the minimum-tension choice
beta = beta_min.

The knot is not measured. Its start is predicted from the two tool tips: at
the height of their midpoint, on the normal through the seat point p_0 =
(p_a + p_b)/2. The post end (strand anchored at the entry point p_a, 7.1)
follows ``end1`` of :func:`suture_engine.suture.knot.placement_trajectory`,
the loop end (anchored at p_b) ``end2``; on a square knot's second throw
(``throw: 2``) the anchors are the other way round (7.1-7.3). The tools first
move straight to the trajectories' starts, then follow them with minimum-jerk
timing whose peak knot sliding rate is ``speed``.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef, RoleRef
from suture_engine.language.units import Angle, Force, Speed

__all__ = ["PlaceKnot", "PlaceKnotParams", "wound_points"]


def wound_points(ctx: Any, site: str) -> tuple[Any, Any, Any]:
    """The knot site and its stitch's entry and exit points [m], in the world frame.

    A site named ``knot_<k>`` pairs with the scene's ``entry_<k>`` and ``exit_<k>``;
    without them, the observation's declared ``entry`` and ``exit`` points are used.

    Args:
        ctx: the skill context (its scene's tissue points).
        site: the knot site's name in the scene.

    Returns:
        ``(site, p_a, p_b)``: the site, the entry point and the exit point [m].

    Raises:
        KeyError: the scene names no such site.
    """
    import numpy as np

    points = ctx.scene.tissue.points if ctx.scene is not None else {}
    if site not in points:
        raise KeyError(f"no tissue point named {site!r}; known: {sorted(points)}")
    where = np.array(points[site], dtype=float)
    suffix = site.split("_", 1)[1] if "_" in site else ""
    entry, exit = f"entry_{suffix}", f"exit_{suffix}"
    if suffix and entry in points and exit in points:
        return where, np.array(points[entry], float), np.array(points[exit], float)
    pa = np.array(ctx.start.scene.entry_point, dtype=float)
    pb = np.array(ctx.start.scene.exit_point, dtype=float)
    return where, pa, pb


class PlaceKnotParams(SkillParams):
    """Parameters of ``place-knot``."""

    post: RoleRef
    """The role holding the post strand."""
    loop: RoleRef
    """The role holding the loop strand."""
    site: PointRef
    """Where the knot is seated on the tissue, named in the scene."""
    max_tension: Force | None = Field(default=None, gt=0.0)
    """Tension bound while sliding [N]; at most the scene's limit."""
    friction: float = Field(default=0.2, ge=0.0, le=2.0)
    """Suture-suture friction coefficient mu of the sliding condition (4.30) [-]."""
    beta: Literal["min"] | Angle = "min"
    """Pulling angle beta [rad], or ``min`` for the minimum-tension choice."""
    speed: Speed = Field(default=0.005, gt=0.0, le=0.1)
    """Knot sliding speed [m/s]."""
    throw: Literal[1, 2] = 1
    """Which throw of a square knot is placed. On the second the strands leave the knot the
    other way round (7.1-7.3): the post strand is anchored at the exit point and pulled
    towards the entry's side, the loop strand anchored at the entry and pulled towards
    the exit's side."""
    seat_tension: Force | None = Field(default=None, gt=0.0)
    """The knot is taken as seated once the tension estimated from either tool's base
    force/torque sensor along its strand (7.6-7.10, tared as the slide starts) reaches
    this [N]: the tools stop where they are, short of the trajectories' ends (the strands
    were shorter than predicted from the tool tips), and the skill succeeds. None: the
    skill succeeds only at the ends."""


class PlaceKnot(Skill):
    """Slide the knot to ``site`` under ``max_tension`` [N].

    Fails when the pulling angle violates the sliding condition (4.31) on the
    way (:class:`suture_engine.suture.knot.PlacementInfeasible`), when the knot
    (predicted from the tool tips) is not above the seat, when a path leaves
    the joint limits, or when a tip is not within :attr:`TOLERANCE` [m] of its
    end :attr:`SETTLE_S` [s] after the path. ``max_tension`` is enforced by the
    state's invariant, not here. :meth:`metrics` reports the predicted knot
    placement error (4.5.1) from the measured tool tips.
    """

    name: ClassVar[str] = "place-knot"
    Params: ClassVar[type[SkillParams]] = PlaceKnotParams
    tools: ClassVar[tuple[str, ...] | None] = None

    BETA_MIN: ClassVar[float] = 0.0
    """beta_min [rad]: the thesis pulls parallel to the tissue (4.40)."""
    SEAT_HEIGHT: ClassVar[float] = 0.5e-3
    """Knot height above the tissue where sliding stops [m]."""
    APPROACH_SPEED: ClassVar[float] = 0.01
    """Tip speed of the move to the trajectories' starts [m/s]."""
    TOLERANCE: ClassVar[float] = 1e-3
    """Tip position tolerance at the end [m]."""
    SETTLE_S: ClassVar[float] = 1.0
    """Time after the path to reach the tolerance [s]."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._robots: tuple[str, str] = ("", "")
        self._bases: tuple[Any, Any] = (None, None)
        self._paths: list[tuple[Any, Any]] = []
        self._failure = ""
        self._t0 = 0.0
        self.trajectory: Any = None
        self._pa: Any = None
        self._pb: Any = None
        self._n: Any = None
        self._result: dict[str, float] = {}
        self._estimators: list[Any] = []

    def start(self, ctx: Any) -> None:
        """Predict the knot, compute the end trajectories (4.36-4.40) and plan both tools.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        import numpy as np

        from skills.tool_path import ToolPath, duration_for, ik_world, joint_box, tip_world
        from suture_engine.suture.knot import placement_trajectory

        p = self.params
        assert isinstance(p, PlaceKnotParams)
        self._robots = (ctx.robot(p.post), ctx.robot(p.loop))
        self._bases = (ctx.base_poses.get(self._robots[0]), ctx.base_poses.get(self._robots[1]))
        self._t0 = ctx.t0
        self._failure = ""
        self._result = {}
        self._estimators = []
        site, self._pa, self._pb = wound_points(ctx, p.site)
        normal = np.asarray(ctx.start.scene.tissue_normal, dtype=float)
        if ctx.scene is not None:
            normal = np.asarray(ctx.scene.tissue.normal, dtype=float)
        self._n = normal / np.linalg.norm(normal)
        q0 = [np.array(ctx.start.robots[r].q) for r in self._robots]
        tips = [tip_world(q, b) for q, b in zip(q0, self._bases, strict=True)]
        h0 = float((0.5 * (tips[0] + tips[1]) - site) @ self._n)
        knot0 = site + h0 * self._n
        if h0 <= self.SEAT_HEIGHT:
            self._failure = f"predicted knot height {h0 * 1e3:.2f} mm: not above the seat"
            return
        lengths = (
            float(np.linalg.norm(tips[0] - knot0)),
            float(np.linalg.norm(tips[1] - knot0)),
        )
        anchors = (self._pa, self._pb) if p.throw == 1 else (self._pb, self._pa)
        try:
            self.trajectory = placement_trajectory(
                *anchors,
                knot0,
                self._n,
                rate=1.0,
                mu=p.friction,
                lengths=lengths,
                beta_min=self.BETA_MIN,
                beta=None if p.beta == "min" else float(p.beta),
                seat_height=self.SEAT_HEIGHT,
                dt=1e-4,
            )
        except Exception as exc:  # PlacementInfeasible or bad geometry: the skill's failure
            self._failure = f"{type(exc).__name__}: {exc}"
            return
        traj = self.trajectory
        tau = traj.time / traj.time[-1]
        duration = duration_for(float(traj.height[0] - traj.height[-1]), p.speed)
        self._paths = []
        for i, (q, base) in enumerate(zip(q0, self._bases, strict=True)):
            ends = traj.end1 if i == 0 else traj.end2
            roll = float(q[2])
            a, b = tips[i], ends[0]

            def along(s: float, ends: Any = ends, roll: float = roll, base: Any = base) -> Any:
                point = np.array([np.interp(s, tau, ends[:, k]) for k in range(3)])
                return ik_world(point, roll, base)

            def approach(
                s: float, a: Any = a, b: Any = b, roll: float = roll, base: Any = base
            ) -> Any:
                return ik_world(a + s * (b - a), roll, base)

            self._paths.append(
                (
                    ToolPath(
                        approach, duration_for(float(np.linalg.norm(b - a)), self.APPROACH_SPEED)
                    ),
                    ToolPath(along, duration),
                )
            )
        for robot, paths in zip(self._robots, self._paths, strict=True):
            box = joint_box(ctx, robot)
            for path in paths:
                self._failure = self._failure or path.first_violation(box)

    def step(self, ctx: Any, obs: Any) -> Any:
        """Move both tools to the trajectories' starts, then slide the knot down.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        import numpy as np

        from skills.tool_path import tip_world
        from suture_engine.runtime.observation import (
            Command,
            RobotCommand,
            SkillStatus,
            StepResult,
        )
        from suture_engine.suture.knot import placement_error

        p = self.params
        assert isinstance(p, PlaceKnotParams)
        # no tool command: each tool keeps its grip as it is (the stitcher may hold its
        # strand by the needle in either jaw; closing jaw 1 as well left both closed after a
        # first throw, and the next pass could not tell which jaw held the needle)
        if self._failure:
            cmd = Command({r: RobotCommand.position(obs.robots[r].q) for r in self._robots})
            return StepResult(cmd, SkillStatus.FAILURE, self._failure)
        t = obs.t - self._t0
        t_approach = max(first.duration for first, _ in self._paths)
        commands = {}
        done_all = True
        for robot, (first, slide) in zip(self._robots, self._paths, strict=True):
            if t < t_approach:
                q, qd, _ = first.sample(t)
                done_all = False
            else:
                q, qd, done = slide.sample(t - t_approach)
                done_all = done_all and done
            commands[robot] = RobotCommand.position(q, qd)
        cmd = Command(commands)
        if p.seat_tension is not None and t >= t_approach:
            seated = self._seated(ctx, obs, p.seat_tension)
            if seated is not None:
                hold = Command({r: RobotCommand.position(c.q) for r, c in commands.items()})
                self._result = {
                    "knot_placement_seat_tension_N": seated,
                    "knot_placement_slide_fraction": min(
                        1.0, (t - t_approach) / self._paths[0][1].duration
                    ),
                }
                return StepResult(hold, SkillStatus.SUCCESS)
        if not done_all:
            return StepResult(cmd)
        traj = self.trajectory
        ends = (traj.end1[-1], traj.end2[-1])
        tips = [
            tip_world(obs.robots[r].q, b) for r, b in zip(self._robots, self._bases, strict=True)
        ]
        errs = [float(np.linalg.norm(tip - end)) for tip, end in zip(tips, ends, strict=True)]
        slide_time = t - t_approach - self._paths[0][1].duration
        if max(errs) > self.TOLERANCE:
            if slide_time >= self.SETTLE_S:
                return StepResult(
                    cmd, SkillStatus.FAILURE, f"tool tips {max(errs) * 1e3:.2f} mm off their ends"
                )
            return StepResult(cmd)
        shift = 0.5 * ((tips[0] - ends[0]) + (tips[1] - ends[1]))
        err = placement_error(traj.knot[-1] + shift, self._pa, self._pb, self._n)
        self._result = {
            "knot_placement_error_m": err.total,
            "knot_placement_height_m": err.height,
            "knot_placement_lateral_m": err.lateral,
            "knot_placement_beta_rad": float(traj.beta[-1, 0]),
            "knot_placement_min_beta_max_rad": float(np.min(traj.beta_max)),
        }
        return StepResult(cmd, SkillStatus.SUCCESS)

    def _seated(self, ctx: Any, obs: Any, seat: float) -> float | None:
        """The largest strand tension estimate [N] once it reaches ``seat``, else None. The
        estimators (one per tool, along the pull from the predicted knot to the tool tip at
        the slide's start) are set up and tared on the slide's first tick."""
        import numpy as np

        from suture_engine.suture.tension import mounted_estimator

        if not self._estimators:
            traj = self.trajectory
            for robot, base, ends in zip(
                self._robots, self._bases, (traj.end1, traj.end2), strict=True
            ):
                pull = np.asarray(ends[0], float) - np.asarray(traj.knot[0], float)
                ro = obs.robots[robot]
                est, _ = mounted_estimator(
                    None if base is None else base[1], pull, ro.base_wrench, ro.q, ctx.dt, 20.0
                )
                self._estimators.append(est)
            return None
        top = max(
            est.update(obs.robots[r].base_wrench, obs.robots[r].q).tension
            for est, r in zip(self._estimators, self._robots, strict=True)
        )
        return float(top) if top >= seat else None

    def metrics(self) -> dict[str, float]:
        """The predicted knot placement error (4.5.1) [m] and the pulling angles [rad]."""
        return dict(self._result)
