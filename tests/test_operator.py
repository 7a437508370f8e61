"""The scripted operator file: parsing, located errors, timed and conditional events."""

from __future__ import annotations

from pathlib import Path

import pytest

from suture_engine.runtime.operator import (
    OperatorFileError,
    ScriptedOperator,
    load_operator_file,
)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "ops.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_timed_and_conditional_events_fire_once(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        """
events:
  - {at: 3.2 s, do: lock}
  - {when: state = tighten, do: resume, step: tighten}
  - {at: 500 ms, do: force, robot: endobot_1, force: [0, 0, 1], duration: 20 ms}
""",
    )
    op = ScriptedOperator(path, dt=1e-3)
    assert not op.exhausted
    assert [e.action for e in op.poll(0.4995, "autonomous/a", "a", "autonomous")] == ["force"]
    force = op.poll(0.0, "x", None, "lock")
    assert force == []
    assert op.poll(3.1, "autonomous/a", "a", "autonomous") == []
    fired = op.poll(3.2, "autonomous/tighten", "tighten", "autonomous")
    assert [(e.action, e.step) for e in fired] == [("lock", None), ("resume", "tighten")]
    assert op.exhausted
    assert op.poll(10.0, "autonomous/tighten", "tighten", "autonomous") == []


def test_conditional_event_with_after_fires_that_long_after_the_condition(
    tmp_path: Path,
) -> None:
    path = _write(
        tmp_path,
        """
events:
  - {when: state = push, after: 1.5 s, do: push, robot: endobot_1, velocity: [0, 0.01, 0]}
  - {when: state = push, do: lock}
""",
    )
    op = ScriptedOperator(path, dt=1e-3)
    assert op.poll(0.0, "autonomous/a", "a", "autonomous") == []
    assert op.poll(5.0, "autonomous/a", "a", "autonomous") == []  # not yet in 'push'
    assert [e.action for e in op.poll(7.0, "autonomous/push", "push", "autonomous")] == ["lock"]
    assert op.poll(8.4985, "autonomous/push", "push", "autonomous") == []
    [ev] = op.poll(8.4995, "autonomous/push", "push", "autonomous")  # 7.0 + 1.5 - dt/2
    assert ev.action == "push" and ev.velocity == (0.0, 0.01, 0.0)
    assert op.poll(20.0, "autonomous/push", "push", "autonomous") == []


def test_after_needs_a_condition(tmp_path: Path) -> None:
    with pytest.raises(OperatorFileError, match="after"):
        load_operator_file(_write(tmp_path, "- {at: 1 s, after: 2 s, do: lock}\n"))


def test_a_procedure_declares_its_operator_file(tmp_path: Path) -> None:
    from suture_engine.runtime.run import declared_operator_file

    proc = tmp_path / "p" / "proc.yaml"
    assert (
        declared_operator_file(proc, {"operator_file": "ops.yaml"}) == tmp_path / "p" / "ops.yaml"
    )
    assert declared_operator_file(proc, {"operator_file": ""}) is None
    assert declared_operator_file(proc, {"duration": 3.0}) is None
    absolute = tmp_path / "elsewhere.yaml"
    assert declared_operator_file(proc, {"operator_file": str(absolute)}) == absolute


def test_force_event_fields_are_si(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "- {at: 1, do: force, robot: endobot_2, force: [1, 2, 3], duration: 250 ms}\n",
    )
    [(_, ev)] = load_operator_file(path)
    assert ev.force == (1.0, 2.0, 3.0) and ev.duration == pytest.approx(0.25)
    assert ev.robot == "endobot_2" and ev.source == "scripted"


@pytest.mark.parametrize(
    ("text", "line", "column", "path", "words"),
    [
        ("events:\n  - {at: 1 s, do: jump}\n", 2, 19, "events[0].do", "lock"),
        ("events:\n  - {do: lock}\n", 2, 5, "events[0]", "exactly one"),
        ("events:\n  - {at: soon, do: lock}\n", 2, 10, "events[0].at", "3.2 s"),
        ("events:\n  - {at: 1, when: state = a, do: lock}\n", 2, 5, "events[0]", "exactly one"),
        ("events:\n  - {when: state is a, do: lock}\n", 2, 12, "events[0].when", "state = NAME"),
        ("events:\n  - {at: 1, do: force, robot: endobot_1}\n", 2, 5, "events[0]", "force"),
        ("events:\n  - {at: 1, do: lock, colour: red}\n", 2, 23, "events[0].colour", "xtra"),
    ],
)
def test_errors_are_located(
    tmp_path: Path, text: str, line: int, column: int, path: str, words: str
) -> None:
    file = _write(tmp_path, text)
    with pytest.raises(OperatorFileError) as err:
        load_operator_file(file)
    e = err.value
    assert (e.line, e.column, e.path) == (line, column, path), str(e)
    assert words.lower() in str(e).lower()
    assert str(e).startswith(f"{file}:{line}:{column}")


def test_not_yaml_and_missing_file_are_typed_errors(tmp_path: Path) -> None:
    with pytest.raises(OperatorFileError) as err:
        load_operator_file(_write(tmp_path, "events: [\n"))
    assert err.value.line >= 1
    with pytest.raises(OperatorFileError, match="cannot read"):
        load_operator_file(tmp_path / "absent.yaml")


def test_resume_target_must_be_a_step(tmp_path: Path) -> None:
    op = ScriptedOperator(_write(tmp_path, "- {at: 1, do: resume, step: nowhere}\n"))
    with pytest.raises(OperatorFileError, match="nowhere"):
        op.check_steps(["a", "b"])


def test_interactive_keys_become_operator_events(monkeypatch: pytest.MonkeyPatch) -> None:
    import io
    import sys

    from suture_engine.runtime.operator import InteractiveOperator

    monkeypatch.setattr(sys, "stdin", io.StringIO("lmxRa"))
    op = InteractiveOperator()
    op._thread.join(timeout=5)
    events = op.poll(0.0, "lock", None, "lock")
    assert [e.action for e in events] == ["lock", "manual", "resume", "abort"]
    assert {e.source for e in events} == {"interactive"}
    assert op.poll(0.1, "lock", None, "lock") == []
    op.close()
