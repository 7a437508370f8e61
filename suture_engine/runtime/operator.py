"""The operator channel: the surgeon's events (thesis 4.6.2, HDES of Fig. 4.22).

Two sources, one interface (:meth:`poll` once per tick):

- :class:`ScriptedOperator` reads an operator file (``--operator ops.yaml``)::

      events:
        - at: 3.2 s          # timed: at the first tick with t >= 3.2 s
          do: lock
        - when: state = tighten   # conditional: the first tick the condition holds
          do: resume
        - at: 1.0 s
          do: force          # the simulated surgeon pushes the tool tip
          robot: endobot_1
          force: [0.0, 0.0, -1.0]   # [N], world frame
          duration: 0.5 s
        - at: 2.0 s
          do: push           # the surgeon's hand moves at a velocity and drags the
          robot: endobot_1   # tool tip through an impedance: F = K (x_hand - x_tip)
          velocity: [0.01, 0.0, 0.0]   # [m/s], world frame, from the tip's position
          stiffness: 200 N/m
          duration: 1 s
        - when: state = along-line    # conditional with a delay: 1.5 s after the
          after: 1.5 s                # first tick the condition holds
          do: push
          robot: endobot_1
          velocity: [0.0, 0.01, 0.0]
          duration: 1 s

  Actions: ``lock``, ``manual``, ``resume`` (optional ``step``), ``abort``,
  ``force``, ``push``. ``lock``/``manual``/``resume`` with ``robot: NAME`` act on
  that EndoBot alone (Fig. 4.23): the procedure goes on with the other one, and a
  step that needs the held robot waits (locked) until it is given back with
  ``resume`` + ``robot``. Each event fires once. Errors name the file, line and column.
- :class:`InteractiveOperator` reads single keys from the terminal:
  ``l`` lock, ``m`` manual, ``r`` resume, ``a`` abort.
"""

from __future__ import annotations

import re
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from suture_engine.errors import SutureError

__all__ = [
    "InteractiveOperator",
    "OperatorEvent",
    "OperatorFileError",
    "OperatorFileMissing",
    "ScriptedOperator",
    "load_operator_file",
]

Action = Literal["lock", "manual", "resume", "abort", "force", "push"]
_STIFFNESS = re.compile(r"^\s*([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*(N/m|N/mm)?\s*$")
_TIME = re.compile(r"^\s*([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*(s|ms|min)?\s*$")
_SCALE = {"s": 1.0, "ms": 1e-3, "min": 60.0, None: 1.0}
_WHEN = re.compile(r"^\s*(state|mode)\s*=\s*([A-Za-z0-9_\-./~]+)\s*$")
_MODES = ("lock", "manual", "autonomous")


class OperatorFileError(SutureError):
    """An operator file that cannot be used.

    Attributes:
        file: the file.
        line: 1-based line (0 when unknown).
        column: 1-based column (0 when unknown).
        path: the field path ("events[2].at").
    """

    code = "operator-file"

    def __init__(self, file: str, message: str, line: int = 0, column: int = 0, path: str = ""):
        where = f"{file}:{line}:{column}" if line else file
        super().__init__(f"{where}: {path + ': ' if path else ''}{message}")
        self.file = file
        self.line = line
        self.column = column
        self.path = path


def _seconds(value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError("expected a time such as 3.2 s")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        m = _TIME.match(value)
        if m:
            return float(m.group(1)) * _SCALE[m.group(2)]
    raise ValueError(f"expected a time such as '3.2 s' or '500 ms', found {value!r}")


class _Event(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)

    at: float | None = None
    when: str | None = None
    do: Action
    step: str | None = None
    robot: str | None = None
    force: tuple[float, float, float] | None = None
    velocity: tuple[float, float, float] | None = None
    stiffness: float = Field(default=200.0, gt=0.0)
    duration: float = Field(default=0.0, ge=0.0)
    after: float = Field(default=0.0, ge=0.0)

    @field_validator("stiffness", mode="before")
    @classmethod
    def _stiffness(cls, v: Any) -> Any:
        if isinstance(v, str):
            m = _STIFFNESS.match(v)
            if not m:
                raise ValueError(f"expected a stiffness such as '200 N/m', found {v!r}")
            return float(m.group(1)) * (1000.0 if m.group(2) == "N/mm" else 1.0)
        return v

    @field_validator("at", "duration", "after", mode="before")
    @classmethod
    def _time(cls, v: Any) -> Any:
        return None if v is None else _seconds(v)

    @field_validator("when")
    @classmethod
    def _cond(cls, v: str | None) -> str | None:
        m = _WHEN.match(v) if v is not None else None
        if v is not None and (m is None or (m.group(1) == "mode" and m.group(2) not in _MODES)):
            raise ValueError(
                f"expected 'state = NAME' or 'mode = lock|manual|autonomous', got {v!r}"
            )
        return v

    @model_validator(mode="after")
    def _one_trigger(self) -> _Event:
        if (self.at is None) == (self.when is None):
            raise ValueError("give exactly one of 'at' (a time) or 'when' (a condition)")
        if self.at is not None and self.at < 0:
            raise ValueError("'at' must be >= 0 s")
        if self.do == "force" and (self.force is None or self.robot is None):
            raise ValueError("a 'force' event needs 'robot' and 'force' [N]")
        if self.do != "force" and self.force is not None:
            raise ValueError("'force' is only for 'do: force'")
        if self.do == "push" and (self.velocity is None or self.robot is None):
            raise ValueError("a 'push' event needs 'robot' and 'velocity' [m/s]")
        if self.do != "push" and self.velocity is not None:
            raise ValueError("'velocity' is only for 'do: push'")
        if self.step is not None and self.do != "resume":
            raise ValueError("'step' is only for 'do: resume'")
        if self.after and self.when is None:
            raise ValueError("'after' is only for a conditional ('when') event")
        return self


class _File(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)

    events: list[_Event]


@dataclass(frozen=True)
class OperatorEvent:
    """One operator event as the interpreter receives it.

    Attributes:
        action: lock, manual, resume, abort, force or push.
        step: the step to resume at (None: the interrupted one).
        robot: the robot a force acts on.
        force: the force at the tool tip [N], world frame (``force``).
        duration: how long the force or push acts [s].
        source: "scripted", "interactive" or "replay".
        index: the event's position in its file (-1 otherwise).
        velocity: the hand's velocity [m/s], world frame (``push``).
        stiffness: the hand's impedance stiffness [N/m] (``push``).
    """

    action: str
    step: str | None = None
    robot: str | None = None
    force: tuple[float, float, float] | None = None
    duration: float = 0.0
    source: str = "scripted"
    index: int = -1
    velocity: tuple[float, float, float] | None = None
    stiffness: float = 0.0


class OperatorFileMissing(OperatorFileError):
    """The operator file cannot be read (missing, a folder, unreadable): an I/O error."""

    code = "operator-file-io"


_FIXED_STATES = ("idle", "lock", "manual")
"""Automaton states every procedure has (besides its steps and terminals)."""


def _load(path: str | Path) -> tuple[list[tuple[_Event, OperatorEvent]], list[tuple[int, int]]]:
    """The file's events and each event's (line, column), both 1-based."""
    from suture_engine.language.source import load_yaml_text
    from suture_engine.validation.problem import ProblemError

    file = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise OperatorFileError(file, f"not UTF-8 text: {exc.reason}", 1, 1) from None
    except OSError as exc:
        raise OperatorFileMissing(file, f"cannot read: {exc.strerror or exc}") from None
    try:
        doc = load_yaml_text(text, file)
    except ProblemError as exc:
        p = exc.problems[0]
        message = f"not valid YAML: {p.code}: {p.message}"
        raise OperatorFileError(file, message, p.line or 1, p.column or 1, p.path) from None
    data, source = doc.data, doc.source
    listed = isinstance(data, list)  # a bare list of events
    if listed:
        data = {"events": data}

    def where(loc: Sequence[int | str]) -> tuple[int | str, ...]:
        return tuple(loc[1:]) if listed and loc[:1] == ["events"] else tuple(loc)

    try:
        parsed = _File.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = [p for p in err["loc"] if not (isinstance(p, str) and p.startswith("function-"))]
        key = source.keys.get(where(loc)) if err["type"] == "extra_forbidden" else None
        line, col = key if key is not None else source.locate(where(loc))
        dotted = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in loc).lstrip(".")
        raise OperatorFileError(file, err["msg"], line, col, dotted) from None
    events = [
        (
            e,
            OperatorEvent(
                e.do, e.step, e.robot, e.force, e.duration, "scripted", i, e.velocity, e.stiffness
            ),
        )
        for i, e in enumerate(parsed.events)
    ]
    return events, [source.locate(where(["events", i])) for i in range(len(events))]


def load_operator_file(path: str | Path) -> list[tuple[_Event, OperatorEvent]]:
    """Read and validate an operator file.

    The file is read with the procedure language's safe YAML loader (standard tags
    only; nesting, aliases and size bounded; every node located).

    Raises:
        OperatorFileMissing: the file cannot be read (an I/O error).
        OperatorFileError: not YAML, or an invalid event (located).
    """
    return _load(path)[0]


class ScriptedOperator:
    """Timed and conditional operator events from an operator file.

    Args:
        path: the operator file.
        dt: the control period [s] (a timed event fires at the first tick with
            ``t >= at - dt / 2``).
    """

    def __init__(self, path: str | Path, dt: float = 1e-3) -> None:
        self._file = str(path)
        self._events, self._where = _load(path)
        self._fired = [False] * len(self._events)
        self._since: list[float | None] = [None] * len(self._events)
        self._half = dt / 2.0

    def check_steps(self, steps: Sequence[str]) -> None:
        """Reject resume targets that are not steps of the procedure (located)."""
        self.check(steps)

    def check(
        self,
        steps: Sequence[str],
        terminals: Sequence[str] = (),
        robots: Sequence[str] | None = None,
    ) -> None:
        """Check the events against the compiled procedure and the scene.

        Args:
            steps: the procedure's steps.
            terminals: its terminal states.
            robots: the scene's robots (None: not checked).

        Raises:
            OperatorFileError: a resume target that is not a step, a ``state =``
                condition on a state the procedure lacks (it would never fire), or a
                robot the scene lacks; located at the event.
        """
        from suture_engine.runtime.automaton import ABORTED, FAILED

        states = {*steps, *terminals, *_FIXED_STATES, ABORTED, FAILED}
        states |= {f"autonomous/{s}" for s in steps} | {f"autonomous/{s}~notbe" for s in steps}
        for (spec, ev), (line, col) in zip(self._events, self._where, strict=True):
            path = f"events[{ev.index}]"
            if ev.step is not None and ev.step not in steps:
                raise OperatorFileError(
                    self._file,
                    f"no step {ev.step!r} (steps: {', '.join(steps)})",
                    line,
                    col,
                    f"{path}.step",
                )
            m = _WHEN.match(spec.when or "")
            if m is not None and m.group(1) == "state" and m.group(2) not in states:
                raise OperatorFileError(
                    self._file,
                    f"no state {m.group(2)!r}: the condition would never hold "
                    f"(steps: {', '.join(steps)}; terminals: {', '.join(terminals) or '-'})",
                    line,
                    col,
                    f"{path}.when",
                )
            if robots is not None and ev.robot is not None and ev.robot not in robots:
                raise OperatorFileError(
                    self._file,
                    f"no robot {ev.robot!r} in the scene (robots: {', '.join(robots)})",
                    line,
                    col,
                    f"{path}.robot",
                )

    @property
    def exhausted(self) -> bool:
        """True when no timed event is left (conditional ones may still fire)."""
        return all(
            f or spec.at is None for f, (spec, _) in zip(self._fired, self._events, strict=True)
        )

    def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
        """Events that fire at time ``t`` [s] in automaton state ``state``."""
        out: list[OperatorEvent] = []
        for i, (spec, ev) in enumerate(self._events):
            if self._fired[i]:
                continue
            if spec.at is not None:
                hit = t >= spec.at - self._half
            else:
                m = _WHEN.match(spec.when or "")
                assert m is not None
                what, name = m.group(1), m.group(2)
                hit = (name in (state, step)) if what == "state" else name == mode
                if hit and spec.after > 0.0:
                    # Delayed: the clock starts at the first tick the condition holds.
                    since = self._since[i]
                    if since is None:
                        since = self._since[i] = t
                    hit = t >= since + spec.after - self._half
            if hit:
                self._fired[i] = True
                out.append(ev)
        return out


class InteractiveOperator:
    """Keys typed in the terminal: l lock, m manual, r resume, a abort.

    A daemon thread reads standard input (in cbreak mode when it is a terminal);
    :meth:`poll` hands over the keys typed since the last tick.
    """

    KEYS: ClassVar[dict[str, str]] = {"l": "lock", "m": "manual", "r": "resume", "a": "abort"}

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._queue: list[OperatorEvent] = []
        self._stop = threading.Event()
        self._restore: Any = None
        if sys.stdin is not None and sys.stdin.isatty():
            try:
                import termios
                import tty

                fd = sys.stdin.fileno()
                old = termios.tcgetattr(fd)
                tty.setcbreak(fd)
                self._restore = lambda: termios.tcsetattr(fd, termios.TCSADRAIN, old)
            except (ImportError, OSError):
                self._restore = None
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            ch = sys.stdin.read(1) if sys.stdin is not None else ""
            if not ch:
                return
            action = self.KEYS.get(ch.lower())
            if action is not None:
                with self._lock:
                    self._queue.append(OperatorEvent(action, source="interactive"))

    def poll(self, t: float, state: str, step: str | None, mode: str) -> list[OperatorEvent]:
        """Keys typed since the last call."""
        with self._lock:
            out, self._queue = self._queue, []
        return out

    def close(self) -> None:
        """Restore the terminal."""
        self._stop.set()
        if self._restore is not None:
            self._restore()
            self._restore = None
