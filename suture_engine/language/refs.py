"""Markers for parameter fields that name something in the scene or procedure.

A skill's parameter model marks a string field with :class:`SceneRef` so that
the dry-run can check the name exists: ``PointRef`` names a tissue point of
the scene (``entry_1``), ``RoleRef`` a role of the procedure (``stitcher``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

__all__ = ["PointRef", "RoleRef", "SceneRef"]


@dataclass(frozen=True)
class SceneRef:
    """Marks a string field as a reference.

    Attributes:
        kind: ``"point"`` (a named tissue point of the scene) or ``"role"``
            (a role declared under the procedure's ``roles``).
    """

    kind: Literal["point", "role"]


PointRef = Annotated[str, SceneRef("point")]
"""The name of a tissue point of the scene (``entry_1``)."""
RoleRef = Annotated[str, SceneRef("role")]
"""The name of a role of the procedure (``stitcher``, ``grasper``)."""
