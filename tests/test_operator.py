"""The scripted operator file: parsing, located errors, timed and conditional events."""

from __future__ import annotations

from pathlib import Path

import pytest

from suture_engine.runtime.operator import (
    OperatorFileError,
    OperatorFileMissing,
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
    file = _write(tmp_path, "- {at: 1, do: lock}\n- {at: 1, do: resume, step: nowhere}\n")
    op = ScriptedOperator(file)
    with pytest.raises(OperatorFileError, match="nowhere") as err:
        op.check_steps(["a", "b"])
    assert (err.value.line, err.value.column, err.value.path) == (2, 3, "events[1].step")
    assert str(err.value).startswith(f"{file}:2:3:")


STEPS = ("prepare", "tighten")
TERMINALS = ("finished",)
ROBOTS = ("endobot_1", "endobot_2")


@pytest.mark.parametrize(
    "state",
    [
        "tighten",
        "autonomous/tighten",
        "autonomous/tighten~notbe",
        "finished",
        "lock",
        "manual",
        "idle",
        "ABORTED",
    ],
)
def test_conditions_on_states_the_automaton_has_are_accepted(tmp_path: Path, state: str) -> None:
    op = ScriptedOperator(_write(tmp_path, f"events:\n  - {{when: state = {state}, do: lock}}\n"))
    op.check(STEPS, TERMINALS, ROBOTS)


@pytest.mark.parametrize(
    ("event", "path", "words"),
    [
        ("{when: state = nowhere, do: lock}", "events[1].when", "never hold"),
        ("{when: state = autonomous/nowhere, do: lock}", "events[1].when", "nowhere"),
        ("{at: 1 s, do: lock, robot: endobot_7}", "events[1].robot", "endobot_7"),
        ("{at: 1 s, do: push, robot: e3, velocity: [0, 0, 1]}", "events[1].robot", "e3"),
        ("{at: 1 s, do: resume, step: nowhere}", "events[1].step", "nowhere"),
    ],
)
def test_events_the_procedure_or_scene_cannot_honour_are_refused_located(
    tmp_path: Path, event: str, path: str, words: str
) -> None:
    file = _write(tmp_path, f"events:\n  - {{at: 1 s, do: lock}}\n  - {event}\n")
    op = ScriptedOperator(file)
    with pytest.raises(OperatorFileError) as err:
        op.check(STEPS, TERMINALS, ROBOTS)
    assert (err.value.line, err.value.column, err.value.path) == (3, 5, path), str(err.value)
    assert words in str(err.value)


def test_robots_are_not_checked_without_a_scene(tmp_path: Path) -> None:
    op = ScriptedOperator(_write(tmp_path, "- {at: 1 s, do: lock, robot: endobot_7}\n"))
    op.check(STEPS, TERMINALS, None)
    with pytest.raises(OperatorFileError, match="endobot_7"):
        op.check(STEPS, TERMINALS, ROBOTS)


def test_mode_condition_names_a_mode(tmp_path: Path) -> None:
    with pytest.raises(OperatorFileError, match="mode = sleepy") as err:
        load_operator_file(_write(tmp_path, "events:\n  - {when: mode = sleepy, do: lock}\n"))
    assert err.value.line == 2
    [(spec, _)] = load_operator_file(
        _write(tmp_path, "events:\n  - {when: mode = manual, do: resume}\n")
    )
    assert spec.when == "mode = manual"


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("events: " + "[" * 3000 + "]" * 3000 + "\n", "too-deep"),
        ("events: " + "[" * 100 + "]" * 100 + "\n", "too-deep"),
        ("events: !!python/object/apply:os.system ['echo x']\n", "tag"),
        ("a: &a [1, 2]\nevents: *a\nevents: []\n", "duplicate"),
        ("events: [{at: 1 s, do: lock, at: 2 s}]\n", "duplicate"),
    ],
)
def test_the_safe_loader_reads_operator_files(tmp_path: Path, text: str, words: str) -> None:
    file = _write(tmp_path, text)
    with pytest.raises(OperatorFileError) as err:
        load_operator_file(file)
    assert err.value.line >= 1 and err.value.column >= 1, str(err.value)
    assert words in str(err.value)
    assert not isinstance(err.value, OperatorFileMissing)


def test_an_unreadable_file_is_an_io_error(tmp_path: Path) -> None:
    with pytest.raises(OperatorFileMissing, match="cannot read"):
        load_operator_file(tmp_path / "absent.yaml")
    with pytest.raises(OperatorFileMissing):
        load_operator_file(tmp_path)


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
