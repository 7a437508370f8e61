"""Safe YAML loading: positions, duplicate keys, tags, and bounds."""

from __future__ import annotations

import pytest

from suture_engine.language.source import MAX_DEPTH, MAX_FILE_BYTES, load_yaml_text
from suture_engine.validation.problem import ProblemError


def _error(text: str) -> tuple[str, int, int]:
    with pytest.raises(ProblemError) as info:
        load_yaml_text(text, "f.yaml")
    p = info.value.problems[0]
    return p.code, p.line, p.column


def test_every_node_keeps_line_and_column() -> None:
    doc = load_yaml_text("a: 1\nb:\n  c: [1, 2 mm]\n", "f.yaml")
    assert doc.data == {"a": 1, "b": {"c": [1, "2 mm"]}}
    assert doc.source.positions[("b", "c")] == (3, 3)
    assert doc.source.positions[("b", "c", 1)] == (3, 10)
    assert doc.source.locate(("b", "c", 1, "missing")) == (3, 10)


def test_on_is_a_key_not_a_boolean() -> None:
    assert load_yaml_text("on: {done: x}\n", "f").data == {"on": {"done": "x"}}


def test_duplicate_key_is_an_error_at_the_second_key() -> None:
    assert _error("a: 1\nb: 2\na: 3\n") == ("duplicate-key", 3, 1)


@pytest.mark.parametrize(
    "text",
    [
        "a: !!python/object/apply:os.system ['echo hi']\n",
        "a: !!python/name:os.system\n",
        "!custom {a: 1}\n",
        "a: !!binary aGk=\n",
        "a: !!set {x}\n",
        "<<: {a: 1}\n",
    ],
)
def test_no_tag_constructs_objects(text: str) -> None:
    assert _error(text)[0] == "yaml-tag"


def test_alias_expansion_is_bounded() -> None:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 9):
        prev = f"*a{i - 1}"
        lines.append(f"a{i}: &a{i} [{', '.join([prev] * 10)}]")
    assert _error("\n".join(lines) + "\n")[0] == "yaml-too-large"


def test_depth_is_bounded() -> None:
    n = MAX_DEPTH + 5
    assert _error("[" * n + "]" * n)[0] == "yaml-too-deep"
    assert _error("[" * 5000 + "]" * 5000)[0] == "yaml-too-deep"


def test_size_is_bounded() -> None:
    assert _error("a: '" + "x" * MAX_FILE_BYTES + "'\n")[0] == "yaml-too-large"


def test_syntax_error_is_located() -> None:
    code, line, _ = _error("a: 1\nb: [1, 2\n")
    assert code == "yaml-syntax" and line >= 2


def test_complex_keys_are_rejected() -> None:
    assert _error("? [1, 2]\n: 3\n")[0] == "yaml-key"
