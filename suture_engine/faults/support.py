"""Which backend simulates which fault, and the located refusal of the others.

Sensor faults (noise, bias, delay, dropout) and joint faults (joint-lock,
joint-weak) change measurements and commands in the wrapper, so every
simulating backend takes them; so does a NaN blow-up. The others need the
backend: an energy blow-up pushes the tool tip (``apply_external_force``),
a grasp slip and a snag need the thread (the surgical backend's
``inject_grasp_slip`` / ``inject_snag`` hooks). A replayed trace already holds
its measurements: it takes no fault.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from suture_engine.errors import SutureError
from suture_engine.faults.model import FAULT_KINDS, Fault

__all__ = [
    "BACKEND_FAULTS",
    "GENERIC_FAULTS",
    "FaultNotSupported",
    "fault_problems",
    "fault_state_problems",
    "refusal",
    "supported_kinds",
]

_ALL = frozenset(FAULT_KINDS) | {"blow-up:energy"}
GENERIC_FAULTS = frozenset(
    {"noise", "bias", "delay", "dropout", "joint-lock", "joint-weak", "blow-up"}
)
"""What any simulating backend takes (the wrapper does it all; blow-up here is NaN)."""

BACKEND_FAULTS: dict[str, frozenset[str]] = {
    "ideal": GENERIC_FAULTS | {"blow-up:energy"},
    "pybullet": GENERIC_FAULTS | {"blow-up:energy"},
    "pybullet-surgical": _ALL,
    "replay": frozenset(),
}
"""Built-in backend -> the fault kinds it simulates (``blow-up:energy`` for the
exploding-force blow-up)."""


def supported_kinds(backend: str) -> frozenset[str]:
    """The fault kinds ``backend`` simulates.

    Variants of the surgical backend (e.g. ``pybullet-surgical-stitched``) are taken as
    the surgical one. A backend not in :data:`BACKEND_FAULTS` (a plugin) is given every
    kind here: the wrapper then refuses, before the run, a fault whose hook the backend
    does not have (``inject_grasp_slip``, ``inject_snag``, ``apply_external_force``).
    """
    if backend in BACKEND_FAULTS:
        return BACKEND_FAULTS[backend]
    if backend.startswith("pybullet-surgical"):
        return BACKEND_FAULTS["pybullet-surgical"]
    return _ALL


def _key(fault: Fault) -> str:
    return "blow-up:energy" if fault.kind == "blow-up" and fault.mode == "energy" else fault.kind


def refusal(fault: Fault, backend: str) -> str | None:
    """Why ``backend`` cannot simulate ``fault`` (None: it can)."""
    kinds = supported_kinds(backend)
    key = _key(fault)
    if key in kinds:
        return None
    what = "an energy blow-up" if key == "blow-up:energy" else f"a {fault.kind} fault"
    if backend == "replay":
        return f"the replay backend serves recorded measurements: it cannot simulate {what}"
    if fault.kind in ("grasp-slip", "snag"):
        need = "a thread (use --backend pybullet-surgical)"
    else:
        need = "a way to push the tool tip"
    return f"the {backend} backend cannot simulate {what}: it needs {need}"


class FaultNotSupported(SutureError):
    """A fault the chosen backend cannot simulate.

    Attributes:
        backend: the backend's name.
        kind: the fault's kind.
        index: the fault's index in the run's list.
        where: ``file:line:col`` or ``--fault SPEC`` ("" when unknown).
    """

    code = "fault-not-supported"

    def __init__(self, backend: str, kind: str, index: int, reason: str, where: str = "") -> None:
        self.backend = backend
        self.kind = kind
        self.index = index
        self.where = where
        super().__init__(f"{where + ': ' if where else ''}{reason}")


def _scene_source(proc: Any) -> tuple[Any, tuple[Any, ...]] | None:
    """The source map that holds the scene's ``faults:`` and the path prefix to it."""
    from suture_engine.language.scene_file import read_scene
    from suture_engine.language.source import load_yaml_file

    file = Path(str(proc.file))
    try:
        doc = load_yaml_file(file, str(proc.file))
    except Exception:  # the file was loaded once already; a re-read failure is not ours
        return None
    data = doc.data if isinstance(doc.data, dict) else {}
    scene = data.get("scene")
    if isinstance(scene, dict):
        return doc.source, ("scene",)
    if not isinstance(scene, str) or "${" in scene:
        return doc.source, ("scene",)  # a computed scene path: located at `scene:`
    try:
        sdoc = read_scene(file.parent / scene)
    except Exception:
        return None
    return sdoc.source, sdoc.prefix


def _located(proc: Any, items: list[tuple[int, str, str, str]]) -> list[Any]:
    """Problems ``(index, field, code, message)`` at the scene's ``faults[index].field``."""
    from suture_engine.validation.problem import Problem

    if not items:
        return []
    located = _scene_source(proc)
    out: list[Problem] = []
    for i, name, code, message in items:
        if located is None:
            out.append(Problem(code, message, str(proc.file), 1, 1, "scene"))
            continue
        source, prefix = located
        out.append(source.problem(code, message, (*prefix, "faults", i, name)))
    return out


def fault_state_problems(proc: Any, steps: Sequence[str]) -> list[Any]:
    """Located problems for scene faults whose ``when`` names no step of the procedure.

    Args:
        proc: a loaded procedure.
        steps: the compiled plan's step names (``mirrored-knot.tighten``; a fault's
            ``when: tighten`` matches it).
    """
    from suture_engine.faults.schedule import state_matches

    faults: Sequence[Fault] = getattr(getattr(proc, "scene", None), "faults", None) or []
    items = [
        (i, "when", "unknown-state", f"no step {f.when!r} ({', '.join(steps)})")
        for i, f in enumerate(faults)
        if f.when is not None and not any(state_matches(s, f.when) for s in steps)
    ]
    return _located(proc, items)


def fault_problems(proc: Any, backend: str) -> list[Any]:
    """Located problems for the scene's faults that ``backend`` cannot simulate.

    Args:
        proc: a loaded :class:`~suture_engine.language.procedure.Procedure`.
        backend: the backend the procedure is to run on.

    Returns:
        One :class:`~suture_engine.validation.problem.Problem` (code
        ``fault-not-supported``) per refused fault, at its ``kind`` in the scene.
    """
    scene = getattr(proc, "scene", None)
    faults: Sequence[Fault] = getattr(scene, "faults", None) or []
    items = [
        (i, "kind", "fault-not-supported", reason)
        for i, f in enumerate(faults)
        if (reason := refusal(f, backend)) is not None
    ]
    return _located(proc, items)
