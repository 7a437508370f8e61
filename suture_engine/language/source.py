"""Safe YAML loading that keeps the file, line and column of every node.

The document is composed with PyYAML's safe composer (the C one when
available) and converted by hand, so that:

- no tag can construct a Python object: only the standard scalar, sequence
  and mapping tags are accepted, any other tag is an error;
- a duplicate key in a mapping is an error (PyYAML silently keeps the last);
- alias expansion, file size and nesting depth are bounded;
- every node's position is recorded in a :class:`SourceMap` keyed by its path.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from suture_engine.validation.problem import Problem, ProblemError

__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_NODES",
    "SourceMap",
    "YamlDocument",
    "load_yaml_file",
    "load_yaml_text",
]

MAX_FILE_BYTES = 1_000_000
"""Largest procedure or scene file accepted [bytes]."""
MAX_NODES = 100_000
"""Most nodes a document may expand to (bounds alias expansion)."""
MAX_DEPTH = 64
"""Deepest nesting accepted."""

PathKey = tuple[str | int, ...]

_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:timestamp",
}
_Loader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_constructor = yaml.SafeLoader("")


@dataclass
class SourceMap:
    """Positions of a document's nodes, keyed by path.

    Attributes:
        file: the file the document came from.
        positions: path -> (line, column), both 1-based: a scalar's value, or the key
            of a nested mapping or list.
        keys: path -> (line, column) of the mapping key that names the node.
    """

    file: str
    positions: dict[PathKey, tuple[int, int]] = field(default_factory=dict)
    keys: dict[PathKey, tuple[int, int]] = field(default_factory=dict)

    def locate(self, path: PathKey) -> tuple[int, int]:
        """The position of ``path``, or of its nearest located ancestor."""
        key = tuple(path)
        while key:
            if key in self.positions:
                return self.positions[key]
            key = key[:-1]
        return self.positions.get((), (1, 1))

    def problem(self, code: str, message: str, path: PathKey, at_key: bool = False) -> Problem:
        """A :class:`Problem` located at ``path`` of this document (at its key if asked)."""
        key = self.keys.get(tuple(path)) if at_key else None
        line, column = key if key is not None else self.locate(path)
        return Problem(code, message, self.file, line, column, dotted(path))


def dotted(path: PathKey) -> str:
    """``("states", "tie", "with", "target", 0)`` -> ``states.tie.with.target[0]``."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


@dataclass
class YamlDocument:
    """A loaded YAML document: plain data plus its source map.

    Attributes:
        data: the document as dicts, lists and scalars.
        source: where each node was written.
    """

    data: Any
    source: SourceMap


class _Builder:
    def __init__(self, source: SourceMap) -> None:
        self.source = source
        self.count = 0

    def fail(self, code: str, message: str, node: yaml.Node, path: PathKey) -> ProblemError:
        mark = node.start_mark
        problem = Problem(
            code, message, self.source.file, mark.line + 1, mark.column + 1, dotted(path)
        )
        return ProblemError([problem])

    def build(self, node: yaml.Node, path: PathKey, depth: int) -> Any:
        self.count += 1
        if self.count > MAX_NODES:
            raise self.fail(
                "yaml-too-large",
                f"the document expands to more than {MAX_NODES} nodes (alias bomb?)",
                node,
                path,
            )
        if depth > MAX_DEPTH:
            raise self.fail("yaml-too-deep", f"nesting deeper than {MAX_DEPTH} levels", node, path)
        self.source.positions.setdefault(
            path, (node.start_mark.line + 1, node.start_mark.column + 1)
        )
        if isinstance(node, yaml.ScalarNode):
            if node.tag not in _SCALAR_TAGS:
                raise self.fail("yaml-tag", f"tag {node.tag!r} is not allowed", node, path)
            if node.tag == "tag:yaml.org,2002:str" or node.tag == "tag:yaml.org,2002:timestamp":
                # a string's value is its text (what the constructor would return)
                return str(node.value)
            return _constructor.construct_object(node, deep=True)
        if isinstance(node, yaml.SequenceNode):
            if node.tag != "tag:yaml.org,2002:seq":
                raise self.fail("yaml-tag", f"tag {node.tag!r} is not allowed", node, path)
            return [self.build(n, (*path, i), depth + 1) for i, n in enumerate(node.value)]
        if isinstance(node, yaml.MappingNode):
            if node.tag != "tag:yaml.org,2002:map":
                raise self.fail("yaml-tag", f"tag {node.tag!r} is not allowed", node, path)
            out: dict[Any, Any] = {}
            for key_node, value_node in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    raise self.fail("yaml-tag", "merge keys (<<) are not allowed", key_node, path)
                if not isinstance(key_node, yaml.ScalarNode):
                    raise self.fail("yaml-key", "mapping keys must be scalars", key_node, path)
                if key_node.tag not in _SCALAR_TAGS:
                    raise self.fail(
                        "yaml-tag", f"tag {key_node.tag!r} is not allowed", key_node, path
                    )
                # keys keep their text: YAML 1.1 would read `on:` as the boolean true
                key = str(key_node.value)
                if key in out:
                    raise self.fail(
                        "duplicate-key", f"duplicate key {key!r}", key_node, (*path, key)
                    )
                out[key] = self.build(value_node, (*path, key), depth + 1)
                self.source.keys[(*path, key)] = (
                    key_node.start_mark.line + 1,
                    key_node.start_mark.column + 1,
                )
                if not isinstance(value_node, yaml.ScalarNode):
                    # a nested mapping or list is located at its key; a scalar at its value
                    self.source.positions[(*path, key)] = (
                        key_node.start_mark.line + 1,
                        key_node.start_mark.column + 1,
                    )
            return out
        raise self.fail("yaml-syntax", "unsupported YAML node", node, path)  # pragma: no cover


_PARSE_DEPTH_GUARD = 4 * MAX_DEPTH
"""Nesting at which the event pre-scan stops a document before it is composed [levels]."""


def _check_parse_depth(text: str, file: str) -> None:
    """Refuse a document nested deeper than :data:`_PARSE_DEPTH_GUARD` before composing it.

    The C composer recurses once per level without Python's recursion limit: a few
    hundred kilobytes of ``[[[[...`` crash the process. The event stream is flat, so
    counting its depth is safe. Syntax errors are left for the composer to report.
    """
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_Loader):
            if isinstance(event, yaml.SequenceStartEvent | yaml.MappingStartEvent):
                depth += 1
                if depth > _PARSE_DEPTH_GUARD:
                    mark = event.start_mark
                    line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
                    raise ProblemError(
                        [
                            Problem(
                                "yaml-too-deep",
                                f"nesting deeper than {MAX_DEPTH} levels",
                                file,
                                line,
                                col,
                            )
                        ]
                    )
            elif isinstance(event, yaml.SequenceEndEvent | yaml.MappingEndEvent):
                depth -= 1
    except yaml.YAMLError:
        return


def load_yaml_text(text: str, file: str) -> YamlDocument:
    """Load one YAML document from text.

    Args:
        text: the YAML text.
        file: the name to report in locations.

    Raises:
        ProblemError: a syntax error, a forbidden tag, a duplicate key, or a bound
            exceeded; the problem is located.
    """
    source = SourceMap(file)
    if len(text.encode("utf-8", "replace")) > MAX_FILE_BYTES:
        raise ProblemError(
            [Problem("yaml-too-large", f"file larger than {MAX_FILE_BYTES} bytes", file, 1, 1)]
        )
    _check_parse_depth(text, file)
    try:
        node = yaml.compose(text, Loader=_Loader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
        message = " ".join(str(p) for p in (exc.context, exc.problem) if p) or "invalid YAML"
        raise ProblemError([Problem("yaml-syntax", message, file, line, col)]) from None
    except yaml.YAMLError as exc:
        raise ProblemError([Problem("yaml-syntax", str(exc), file, 1, 1)]) from None
    except RecursionError:
        raise ProblemError(
            [Problem("yaml-too-deep", "nesting too deep to parse", file, 1, 1)]
        ) from None
    if node is None:
        return YamlDocument(None, source)
    try:
        data = _Builder(source).build(node, (), 0)
    except RecursionError:
        raise ProblemError(
            [Problem("yaml-too-deep", "nesting too deep to load", file, 1, 1)]
        ) from None
    except (ValueError, TypeError, OverflowError, yaml.YAMLError) as exc:
        raise ProblemError([Problem("yaml-syntax", f"bad scalar: {exc}", file, 1, 1)]) from None
    return YamlDocument(data, source)


def load_yaml_file(path: Path, display: str | None = None) -> YamlDocument:
    """Load a YAML file (see :func:`load_yaml_text`).

    Args:
        path: the file.
        display: the name to report in locations (default: ``str(path)``).

    Raises:
        ProblemError: ``io-error`` when the file cannot be read, or any problem of
            :func:`load_yaml_text`.
    """
    name = display if display is not None else str(path)
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ProblemError(
                [Problem("yaml-too-large", f"file larger than {MAX_FILE_BYTES} bytes", name, 1, 1)]
            )
        text = path.read_text(encoding="utf-8")
    except ProblemError:
        raise
    except UnicodeDecodeError as exc:
        raise ProblemError(
            [Problem("yaml-syntax", f"the file is not UTF-8 text: {exc.reason}", name, 1, 1)]
        ) from None
    except OSError as exc:
        raise ProblemError([Problem("io-error", f"cannot read file: {exc}", name, 0, 0)]) from None
    return load_yaml_text(text, name)
