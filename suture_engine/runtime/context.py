"""The context a skill receives with :meth:`skills.base.Skill.start` and ``step``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from suture_engine.runtime.observation import Observation

__all__ = ["SkillContext"]


@dataclass(frozen=True)
class SkillContext:
    """What a skill may know besides the tick's observation.

    Attributes:
        step: the procedure state running the skill.
        roles: role -> robot name ("stitcher" -> "endobot_1").
        dt: control period [s].
        start: the observation of the tick the step was entered.
        scene: the procedure's scene model (declared geometry; no ground truth), or None.
        params: the procedure's resolved parameters (SI).
        base_poses: robot -> (base position [m], base rotation matrix row-major 3x3) in the
            world frame; the base origin is the RCM.
        rest: the run's first observation: the robots at rest with the thread slack, where
            the run's own tension estimate is tared (None outside a run).
    """

    step: str
    roles: Mapping[str, str]
    dt: float
    start: Observation
    scene: Any = None
    params: Mapping[str, Any] = field(default_factory=dict)
    base_poses: Mapping[str, tuple[tuple[float, float, float], tuple[float, ...]]] = field(
        default_factory=dict
    )
    rest: Observation | None = None

    @property
    def t0(self) -> float:
        """Simulation time the step was entered [s]."""
        return self.start.t

    def robot(self, role_or_name: str) -> str:
        """The robot name for a role (or a robot name given directly).

        Raises:
            KeyError: neither a role nor a robot of this run.
        """
        if role_or_name in self.roles:
            return self.roles[role_or_name]
        if role_or_name in self.start.robots:
            return role_or_name
        raise KeyError(f"no role or robot named {role_or_name!r}; roles: {sorted(self.roles)}")
