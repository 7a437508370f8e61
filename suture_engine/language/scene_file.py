"""Scene files, and scene files that extend another one (``extends:``).

A scene file may start from another scene file and change only what differs::

    # bench-posts.yaml: the bench with calibration posts
    extends: bench.yaml
    name: bench-posts
    posts:
      stitcher_near: {position: [-30 mm, -50 mm, 0 mm], height: 40 mm, radius: 2 mm}

The extended file's mapping is merged with this one's: a key given here replaces the
extended file's value, except that two mappings are merged key by key (so
``suture: {length: 140 mm}`` changes the thread's length and keeps the rest of its
``suture`` section). Lists and scalars are replaced whole. The path is relative to the
file that names it; an extended file may itself extend another (at most
:data:`MAX_EXTENDS` deep, no cycles). Both the bare form and the ``scene:``-wrapped form
of a scene file can extend and be extended.

A problem in the merged scene is located where the offending value was written: in this
file when it gives the key, else in the extended file.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from suture_engine.language.scene import Scene
from suture_engine.language.source import PathKey, SourceMap, YamlDocument
from suture_engine.validation.problem import Problem, ProblemError

__all__ = [
    "MAX_EXTENDS",
    "LayeredSourceMap",
    "SceneDocument",
    "load_scene",
    "read_scene",
    "resolve_extends",
    "unwrap",
]

MAX_EXTENDS = 8
"""Longest chain of scene files extending one another."""


@dataclass
class LayeredSourceMap(SourceMap):
    """The source map of a merged scene: each path is located in the file that wrote it.

    Paths are relative to the scene; each layer adds its own file's prefix (``scene`` for a
    ``scene:``-wrapped file), so a problem's path reads as in that file.

    Attributes:
        layers: each file's source map and the scene's path in it, the extending file first.
    """

    layers: list[tuple[SourceMap, PathKey]] = field(default_factory=list)

    def _owner(self, path: PathKey) -> tuple[SourceMap, PathKey]:
        # The file that wrote the deepest located ancestor of `path`; on a tie the
        # extending file (it replaced what the extended one wrote).
        key = tuple(path)
        while key:
            for layer, prefix in self.layers:
                if (*prefix, *key) in layer.positions:
                    return layer, prefix
            key = key[:-1]
        return self.layers[0]

    def locate(self, path: PathKey) -> tuple[int, int]:
        """The position of ``path`` in the file that wrote it (see :class:`SourceMap`)."""
        layer, prefix = self._owner(path)
        return layer.locate((*prefix, *path))

    def problem(self, code: str, message: str, path: PathKey, at_key: bool = False) -> Problem:
        """A :class:`Problem` located at ``path`` in the file that wrote it."""
        layer, prefix = self._owner(path)
        return layer.problem(code, message, (*prefix, *path), at_key)


@dataclass
class SceneDocument:
    """A scene's mapping with ``extends`` resolved, and where each part was written.

    Attributes:
        data: the mapping (no ``extends`` key once resolved).
        source: where ``data`` was written.
        prefix: the path of ``data`` in ``source`` (``("scene",)`` for a wrapped file or a
            procedure's inline scene; ``()`` once merged: a layered map adds each file's).
    """

    data: Any
    source: SourceMap
    prefix: PathKey = ()

    def problem(self, code: str, message: str, path: PathKey) -> Problem:
        """A problem at ``path`` (relative to the scene)."""
        return self.source.problem(code, message, (*self.prefix, *path))


def unwrap(doc: YamlDocument, prefix: PathKey = ()) -> SceneDocument:
    """A scene file's mapping without its optional ``scene:`` wrapper.

    Args:
        doc: the loaded file.
        prefix: where the scene sits in ``doc`` (``("scene",)`` for a procedure's inline
            scene); a file holding only a ``scene:`` key is unwrapped too.
    """
    data = doc.data
    for part in prefix:
        data = data[part]
    if not prefix and isinstance(data, dict) and set(data) == {"scene"}:
        data, prefix = data["scene"], ("scene",)
    return SceneDocument(data, doc.source, tuple(prefix))


def _merge(base: Any, over: Any) -> Any:
    if isinstance(base, dict) and isinstance(over, dict):
        out = dict(base)
        for key, value in over.items():
            out[key] = _merge(base[key], value) if key in base else value
        return out
    return over


def resolve_extends(
    scene: SceneDocument,
    here: Path,
    load: Callable[[Path, str], YamlDocument],
    *,
    allowed: Callable[[Path], bool] = lambda _p: True,
    outside_hint: str = "",
    seen: tuple[Path, ...] = (),
) -> SceneDocument:
    """Resolve a scene's ``extends:`` chain into one merged scene.

    Args:
        scene: the scene as written (its ``data`` may hold ``extends``).
        here: the folder that ``extends`` paths are relative to (the scene file's own).
        load: reads a file: ``load(path, display_name)``; raises ProblemError.
        allowed: whether a file may be read (the procedure's folder tree).
        outside_hint: added to the problem when ``allowed`` refuses a file.
        seen: the resolved files already on the chain (the scene's own file, if any).

    Returns:
        ``scene`` itself when it extends nothing, else the merged scene.

    Raises:
        ProblemError: ``scene-extends`` (not a file name, a cycle, a chain longer than
            :data:`MAX_EXTENDS`, a file that holds no mapping), ``missing-scene`` or
            ``include-outside``, located at the ``extends`` key that led there; or a
            problem reading an extended file (its YAML), located in that file.
    """
    data = scene.data
    if not isinstance(data, dict) or "extends" not in data:
        return scene
    ref = data["extends"]
    at = ("extends",)

    def fail(code: str, message: str) -> ProblemError:
        return ProblemError([scene.problem(code, message, at)])

    if not isinstance(ref, str) or not ref.strip():
        raise fail("scene-extends", "`extends` takes a scene file's path (relative to this file)")
    if len(seen) > MAX_EXTENDS:
        raise fail("scene-extends", f"scene files extend one another more than {MAX_EXTENDS} deep")
    target = here / ref
    display = os.path.normpath(os.path.join(os.path.dirname(scene.source.file), ref))
    if not allowed(target):
        raise fail(
            "include-outside", f"scene {ref!r} is outside the procedure's folder tree{outside_hint}"
        )
    key = target.resolve()
    if key in seen:
        raise fail("scene-extends", f"scene files extend each other in a cycle (through {ref!r})")
    if not target.is_file():
        raise fail("missing-scene", f"extended scene file {ref!r} not found")
    base = unwrap(load(target, display))
    if not isinstance(base.data, dict):
        raise fail("scene-extends", f"extended scene file {ref!r} does not hold a mapping")
    base = resolve_extends(
        base,
        target.parent,
        load,
        allowed=allowed,
        outside_hint=outside_hint,
        seen=(*seen, key),
    )
    own = {k: v for k, v in data.items() if k != "extends"}
    below = base.source.layers if isinstance(base.source, LayeredSourceMap) else []
    layers = [(scene.source, scene.prefix), *(below or [(base.source, base.prefix)])]
    return SceneDocument(_merge(base.data, own), LayeredSourceMap(scene.source.file, layers=layers))


def read_scene(path: str | os.PathLike[str]) -> SceneDocument:
    """Read one scene file and resolve its ``extends`` chain (not validated).

    Args:
        path: the scene file.

    Raises:
        ProblemError: the file or a file it extends cannot be read, or an ``extends``
            problem (see :func:`resolve_extends`).
    """
    from suture_engine.language.source import load_yaml_file

    file = Path(path)
    doc = load_yaml_file(file, str(path))
    return resolve_extends(unwrap(doc), file.parent, load_yaml_file, seen=(file.resolve(),))


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Read and validate one scene file (``extends`` resolved).

    Args:
        path: the scene file.

    Raises:
        ProblemError: every problem found, located in the file that wrote it.
    """
    from pydantic import ValidationError

    from suture_engine.language.errors import problems_from_validation

    doc = read_scene(path)
    try:
        return Scene.model_validate(doc.data)
    except ValidationError as exc:
        raise ProblemError(problems_from_validation(exc, doc.source, doc.prefix, Scene)) from None
