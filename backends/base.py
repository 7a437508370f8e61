"""The backend protocol: what the interpreter needs from a simulator or a recording.

A backend is reset with a scene and a seed, then driven tick by tick:
``observe`` (sensor values, no ground truth) -> ``apply`` (joint torques and
tool commands) -> ``step`` (advance one control period). ``ground_truth``
returns what only the simulator knows (suture centerline, true tension), for
the trace and evaluation; it is never handed to skills. ``close`` releases
resources and may be called more than once.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

from suture_engine.errors import SutureError
from suture_engine.runtime.observation import Command, Measurement, SceneGeometry

__all__ = ["Backend", "BackendError", "RunSpec"]


class BackendError(SutureError):
    """A backend cannot do what it was asked (bad scene, closed, end of recording).

    Attributes:
        backend: the backend's registered name.
    """

    code = "backend-error"

    def __init__(self, backend: str, message: str) -> None:
        super().__init__(f"{backend}: {message}")
        self.backend = backend


class RunSpec(Protocol):
    """What a backend reads from the scene to build the world (duck-typed).

    Attributes:
        robots: robot names -> base position [m] and tool kind.
        control_rate_hz: ticks per second [Hz].
    """

    robots: Mapping[str, Any]
    control_rate_hz: float


@runtime_checkable
class Backend(Protocol):
    """A simulator or a recording the interpreter drives tick by tick."""

    name: str

    def reset(self, scene: Any, seed: int) -> Measurement:
        """Build the world from ``scene`` with RNG ``seed``; return the first measurement."""
        ...

    def observe(self) -> Measurement:
        """Measure the current tick (encoders, base wrench, tool states)."""
        ...

    def apply(self, command: Command) -> None:
        """Apply joint torques (``CommandMode.TORQUE``) and tool commands until the next step."""
        ...

    def step(self) -> None:
        """Advance the world by one control period."""
        ...

    def geometry(self) -> SceneGeometry:
        """The declared scene geometry skills may use."""
        ...

    def ground_truth(self) -> Mapping[str, Any]:
        """Simulator-only quantities for the trace (empty when the backend has none)."""
        ...

    def close(self) -> None:
        """Release resources; idempotent."""
        ...
