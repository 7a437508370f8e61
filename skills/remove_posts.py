"""``remove-posts``: the assistant lifts the calibration jig off the bench.

The calibration posts (the scene's ``posts``) are there for ``register``: each robot
touches them with its shaft and its declared base is corrected. Once both bases are
registered the posts have done their work, and on a bench they would be lifted away
before the procedure goes on, so that no later move has to keep clear of them.

The skill moves no robot: on the tick the step starts it asks the runtime to take the
posts out of the world (the backend's ``remove_posts``; a backend without posts fails
the step with its reason), then every robot holds its joints for ``settle`` [s], as
``cut-suture`` and ``load-suture`` do (:class:`skills.reload.SutureChange`). The skills
see the posts only through the scene's declared geometry, which does not change: a
procedure that removes them says so to the steps after it through its own parameters.
"""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from skills.base import SkillParams
from skills.reload import SutureChange
from suture_engine.language.units import Duration

__all__ = ["RemovePosts", "RemovePostsParams"]


class RemovePostsParams(SkillParams):
    """Parameters of ``remove-posts``."""

    settle: Duration = Field(default=0.2, ge=0.0, le=5.0)
    """How long the robots hold still after the posts are taken away [s]."""


class RemovePosts(SutureChange):
    """Take the scene's calibration posts out of the world (see the module docstring)."""

    name: ClassVar[str] = "remove-posts"
    Params: ClassVar[type[SkillParams]] = RemovePostsParams
    action: ClassVar[str] = "remove_posts"
