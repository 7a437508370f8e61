"""``cut-suture`` and ``load-suture``: between the stitches of an interrupted suture.

Each stitch of an interrupted suture has its own suture. Once its knot is tied, the
assistant cuts the ends (``cut-suture``); the tied stitch stays in the tissue, and the
stitcher's jaw is empty. Then a new suture is loaded (``load-suture``): on the stitched
backend its stitch at ``entry``/``exit`` is already made (as that backend's start lays
it), the needle in the jaw of the stitcher that holds it, wherever the stitcher is (on
algorithm 3's bench, the thread's end in the needle holder's jaws); on the plain surgical
backend the thread hangs from the needle. Move the stitcher to where the next stitch
starts before loading. (Loading once the bases are registered, as a real bench does:
``square-knot.yaml``'s ``reload``.)

Neither moves a robot: on the tick the step starts, the skill asks the runtime to change
the suture (the interpreter hands :attr:`SutureChange.scene_request` to the backend; a
backend that cannot fails the step with its reason). Then every robot of the run holds
its joints (4.44) for ``settle`` [s] while the new thread comes to rest, and the step
succeeds. The cut thread's last centerline is kept for evaluation: the summary's
``knot`` has one entry per stitch, cut or not (ground truth, never shown to skills).
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from skills.base import Skill, SkillParams
from suture_engine.language.refs import PointRef
from suture_engine.language.units import Duration

__all__ = ["CutSuture", "CutSutureParams", "LoadSuture", "LoadSutureParams", "SutureChange"]


class CutSutureParams(SkillParams):
    """Parameters of ``cut-suture``."""

    settle: Duration = Field(default=0.2, ge=0.0, le=5.0)
    """How long the robots hold still after the cut [s]."""
    withdraw: bool = False
    """The suture is drawn out of the tissue and discarded (one replaced before any knot,
    e.g. a fresh one loaded once the bases are registered): it leaves the world and is
    not one of the result's stitches (no ``/ground_truth/suture_cut``, no ``knot``
    entry)."""


class LoadSutureParams(SkillParams):
    """Parameters of ``load-suture``."""

    entry: PointRef
    """The new stitch's entry point (a tissue point of the scene)."""
    exit: PointRef
    """Its exit point."""
    settle: Duration = Field(default=0.2, ge=0.0, le=5.0)
    """How long the robots hold still while the new thread comes to rest [s] (the
    stitched start's settling time)."""


class SutureChange(Skill):
    """Ask the backend for one change of the suture (:attr:`Skill.scene_request`, set in
    :meth:`start`), then hold every robot ``settle`` [s]."""

    action: ClassVar[str]
    """The backend's method that makes the change."""

    def __init__(self, params: SkillParams) -> None:
        super().__init__(params)
        self._command: Any = None
        self._t0 = 0.0

    def request(self) -> dict[str, Any]:
        """The backend method's keyword arguments."""
        return {}

    def start(self, ctx: Any) -> None:
        """Hold every robot where it is; ask for the change.

        Args:
            ctx: the :class:`suture_engine.runtime.context.SkillContext`.
        """
        from suture_engine.runtime.observation import Command, RobotCommand

        self._t0 = ctx.t0
        self._command = Command(
            {name: RobotCommand.position(m.q) for name, m in ctx.start.robots.items()}
        )
        self.scene_request = (self.action, self.request())

    def step(self, ctx: Any, obs: Any) -> Any:
        """Hold; succeed ``settle`` [s] after the change.

        Args:
            ctx: the skill context.
            obs: this tick's observation.

        Returns:
            A :class:`suture_engine.runtime.observation.StepResult`.
        """
        from suture_engine.runtime.observation import SkillStatus, StepResult

        settle = float(self.params.settle)  # type: ignore[attr-defined]
        if self.scene_request is None and obs.t - self._t0 >= settle - 0.5 * ctx.dt:
            return StepResult(self._command, SkillStatus.SUCCESS)
        return StepResult(self._command)


class CutSuture(SutureChange):
    """Cut the tied stitch's suture: it leaves the world, its knot kept for evaluation
    (withdrawn: discarded, see :attr:`CutSutureParams.withdraw`)."""

    name: ClassVar[str] = "cut-suture"
    Params: ClassVar[type[SkillParams]] = CutSutureParams
    action: ClassVar[str] = "cut_suture"

    def request(self) -> dict[str, Any]:
        """``withdraw`` when set (a plain cut asks with no arguments)."""
        return {"withdraw": True} if self.params.withdraw else {}  # type: ignore[attr-defined]


class LoadSuture(SutureChange):
    """Load the next stitch's suture at ``entry``/``exit`` (see the module docstring)."""

    name: ClassVar[str] = "load-suture"
    Params: ClassVar[type[SkillParams]] = LoadSutureParams
    action: ClassVar[str] = "load_suture"

    def request(self) -> dict[str, Any]:
        """``entry`` and ``exit``: the new stitch's tissue point names."""
        p = self.params
        assert isinstance(p, LoadSutureParams)
        return {"entry": p.entry, "exit": p.exit}
