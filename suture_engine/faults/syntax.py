"""The ``--fault SPEC`` syntax: one fault in one line, the same vocabulary as ``faults:``.

Grammar (spaces around the separators are allowed)::

    SPEC    := [ROBOT ":"] [TARGET "."] KIND ["=" VALUE] ["@" TRIGGER] [" for " DURATION]
               {";" KEY "=" VALUE}
    TARGET  := ft | enc | encoders                     (noise, bias, delay, dropout)
             | yaw | pitch | roll | insertion | q1..q4 (joint-lock, joint-weak)
    TRIGGER := TIME                                    at a time: "2 s", "150 ms"
             | "state" NAME ["+" TIME]                 when NAME is first entered (+ a delay)
             | "rate" RATE                             random onsets: "rate 2/s"
             | "p" PROBABILITY ["in" TIME]             random, once with that probability
                                                       in the window (default 10 s)
    KEY     := axis | mode | seed | joint | within | at | when
                                                       the other fields of ``faults:``

Examples::

    ft.noise=0.05 N                       force-sensor noise, 0.05 N std, whole run
    ft.bias=0.5 N@2 s                     a 0.5 N bias along z from 2 s on
    ft.delay=2 ms                         the force measurement 2 ms late (thesis 7.4.2)
    endobot_1:enc.dropout@3 s for 20 ms   endobot_1's encoders drop out for 20 ms at 3 s
    ft.dropout@rate 2/s for 10 ms         random 10 ms force dropouts, 2 per second
    endobot_2:grasp-slip@state tighten    the grasp slips when "tighten" is entered
    snag=2 N@state bite+1 s for 300 ms    a 2 N friction spike 1 s into "bite"
    endobot_1:pitch.joint-lock@1 s        endobot_1's pitch joint locks at 1 s
    insertion.joint-weak=0.3@1 s          the insertion's force at 30 % from 1 s on
    blow-up@5 s;mode=energy               an exploding force at 5 s

Errors name the column: :class:`FaultSyntaxError` for the shape,
:class:`FaultValueError` for a field the fault model refuses.
"""

from __future__ import annotations

import re
from typing import Any

from pydantic import ValidationError

from suture_engine.errors import SutureError
from suture_engine.faults.model import FAULT_KINDS, JOINTS, Fault

__all__ = [
    "FaultSpecError",
    "FaultSyntaxError",
    "FaultValueError",
    "format_fault",
    "parse_fault",
]

_TARGETS = {
    "ft": ("sensor", "ft"),
    "enc": ("sensor", "encoders"),
    "encoders": ("sensor", "encoders"),
    **{j: ("joint", j) for j in JOINTS},
    **{f"q{i + 1}": ("joint", j) for i, j in enumerate(JOINTS)},
}
_OPTION_KEYS = ("axis", "mode", "seed", "joint", "within", "at", "when")
_NAME = re.compile(r"[A-Za-z0-9_\-]+$")
_STATE = re.compile(r"[A-Za-z0-9_\-]+(\.[A-Za-z0-9_\-]+)*$")
"""A state name, dotted for a sub-procedure's step (``mirrored-knot.tighten``)."""


class FaultSpecError(SutureError):
    """A ``--fault`` spec that is refused (the base of the two errors below).

    Attributes:
        spec: the spec as given.
        position: 0-based column of the problem in ``spec``.
    """

    code = "bad-fault"

    def __init__(self, spec: str, position: int, message: str) -> None:
        self.spec = spec
        self.position = max(0, min(position, len(spec)))
        caret = " " * self.position + "^"
        super().__init__(
            f"--fault {spec!r}: at column {self.position + 1}: {message}\n  {spec}\n  {caret}"
        )


class FaultSyntaxError(FaultSpecError):
    """The spec does not have the shape of the grammar.

    Attributes:
        expected: what was expected at ``position``.
    """

    def __init__(self, spec: str, position: int, expected: str) -> None:
        self.expected = expected
        super().__init__(spec, position, f"expected {expected}")


class FaultValueError(FaultSpecError):
    """The spec parses, but the fault model refuses a field.

    Attributes:
        field: the refused field (``value``, ``at``, ...; "" for the fault as a whole).
        reason: why.
    """

    def __init__(self, spec: str, position: int, field: str, reason: str) -> None:
        self.field = field
        self.reason = reason
        super().__init__(spec, position, f"{field + ': ' if field else ''}{reason}")


def _strip_span(text: str, start: int, end: int) -> tuple[str, int]:
    """``text[start:end]`` stripped, with the position of its first character."""
    part = text[start:end]
    lead = len(part) - len(part.lstrip())
    return part.strip(), start + lead


_RATE = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(1/s|/s|Hz|hz)?\s*$")


def _rate(text: str) -> str:
    """``2/s``, ``2 /s``, ``2 1/s``, ``2 Hz`` or ``2`` as a quantity in 1/s."""
    match = _RATE.match(text)
    if match is None:
        raise ValueError(text)
    return f"{match.group(1)} 1/s"


def _trigger(spec: str, text: str, pos: int, out: dict[str, Any], where: dict[str, int]) -> None:
    words = text.split(None, 1)
    head = words[0] if words else ""
    rest = words[1] if len(words) > 1 else ""
    rest_pos = pos + (text.find(rest, len(head)) if rest else len(text))
    if head == "state":
        name, _, delay = rest.partition("+")
        name = name.strip()
        if not name or not _STATE.match(name):
            raise FaultSyntaxError(spec, rest_pos, "a state name after 'state'")
        out["when"], where["when"] = name, rest_pos
        if delay.strip():
            out["at"] = delay.strip()
            where["at"] = rest_pos + rest.index("+") + 1
        return
    if head == "rate":
        try:
            out["rate"] = _rate(rest)
        except ValueError:
            raise FaultSyntaxError(spec, rest_pos, "a rate such as '2/s' after 'rate'") from None
        where["rate"] = rest_pos
        return
    if head == "p":
        prob, sep, window = rest.partition(" in ")
        try:
            out["probability"] = float(prob)
        except ValueError:
            raise FaultSyntaxError(spec, rest_pos, "a probability such as 0.5 after 'p'") from None
        where["probability"] = rest_pos
        if sep:
            out["within"] = window.strip()
            where["within"] = rest_pos + rest.index(" in ") + 4
        return
    if not text:
        raise FaultSyntaxError(spec, pos, "a trigger after '@' (a time, state, rate or p)")
    out["at"], where["at"] = text, pos


def _parse(spec: str) -> tuple[dict[str, Any], dict[str, int]]:
    """The spec as a ``faults:`` mapping, with each field's column."""
    out: dict[str, Any] = {}
    where: dict[str, int] = {}
    parts = spec.split(";")
    main_end = len(parts[0])
    offset = main_end + 1
    for part in parts[1:]:
        key, sep, value = part.partition("=")
        key_s, key_pos = _strip_span(spec, offset, offset + len(key))
        if not sep or key_s not in _OPTION_KEYS:
            raise FaultSyntaxError(
                spec, key_pos, f"an option KEY=VALUE with KEY one of {', '.join(_OPTION_KEYS)}"
            )
        val_s, val_pos = _strip_span(spec, offset + len(key) + 1, offset + len(part))
        if not val_s:
            raise FaultSyntaxError(spec, val_pos, f"a value after '{key_s}='")
        out[key_s], where[key_s] = val_s, val_pos
        offset += len(part) + 1
    end = main_end
    for_at = spec.rfind(" for ", 0, end)
    if for_at >= 0:
        dur, dur_pos = _strip_span(spec, for_at + 5, end)
        if not dur:
            raise FaultSyntaxError(spec, dur_pos, "a duration after 'for'")
        out["duration"], where["duration"] = dur, dur_pos
        end = for_at
    at_pos = spec.find("@", 0, end)
    if at_pos >= 0:
        trig, trig_pos = _strip_span(spec, at_pos + 1, end)
        _trigger(spec, trig, trig_pos, out, where)
        end = at_pos
    eq = spec.find("=", 0, end)
    if eq >= 0:
        val, val_pos = _strip_span(spec, eq + 1, end)
        if not val:
            raise FaultSyntaxError(spec, val_pos, "a value after '='")
        if spec[:eq].strip().endswith("blow-up") and val in ("nan", "energy"):
            out["mode"], where["mode"] = val, val_pos
        else:
            out["value"], where["value"] = val, val_pos
        end = eq
    head, head_pos = _strip_span(spec, 0, end)
    if not head:
        raise FaultSyntaxError(spec, head_pos, f"a fault kind ({', '.join(FAULT_KINDS)})")
    robot, colon, rest = head.partition(":")
    if colon:
        if not _NAME.match(robot.strip()):
            raise FaultSyntaxError(spec, head_pos, "a robot name before ':'")
        out["robot"], where["robot"] = robot.strip(), head_pos
        head_pos += len(robot) + 1
        head = rest
    target, dot, kind = head.partition(".")
    if not dot:
        target, kind = "", head
    kind_pos = head_pos + (len(target) + 1 if dot else 0)
    kind = kind.strip()
    if kind not in FAULT_KINDS:
        import difflib

        close = difflib.get_close_matches(kind, FAULT_KINDS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise FaultSyntaxError(
            spec, kind_pos, f"a fault kind ({', '.join(FAULT_KINDS)}), found {kind!r}{hint}"
        )
    out["kind"], where["kind"] = kind, kind_pos
    if dot:
        t = target.strip()
        if t not in _TARGETS:
            raise FaultSyntaxError(
                spec, head_pos, f"a target (ft, enc, yaw, pitch, roll, insertion), found {t!r}"
            )
        field, value = _TARGETS[t]
        out[field], where[field] = value, head_pos
    return out, where


def parse_fault(spec: str) -> Fault:
    """Parse one ``--fault`` spec into a :class:`Fault`.

    Args:
        spec: the spec, e.g. ``"ft.bias=0.5 N@2 s"``.

    Raises:
        FaultSyntaxError: the spec does not follow the grammar (column given).
        FaultValueError: a field is refused by the fault model (column of that field).
    """
    data, where = _parse(spec)
    try:
        return Fault.model_validate(data)
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        loc = [str(p) for p in err.get("loc", ())]
        field = loc[0] if loc else ""
        message = str(err.get("msg", "invalid"))
        message = message.removeprefix("Value error, ")
        if err.get("type") == "literal_error" and "input" in err:
            message += f", found {err['input']!r}"
        return _raise(spec, where.get(field, where.get("kind", 0)), field, message)


def _raise(spec: str, position: int, field: str, message: str) -> Fault:
    raise FaultValueError(spec, position, field, message)


def _num(value: float) -> str:
    return repr(float(value))


def _value_text(fault: Fault) -> str:
    value = fault.value
    assert value is not None
    if fault.kind in ("noise", "bias"):
        if fault.sensor == "ft":
            unit = "N"
        else:
            unit = "m" if fault.joint == "insertion" else "rad"
        return f"{_num(value)} {unit}"
    if fault.kind == "delay":
        return f"{_num(value)} s"
    if fault.kind == "snag":
        return f"{_num(value)} N"
    return _num(value)


def format_fault(fault: Fault) -> str:
    """The ``--fault`` spec of ``fault`` (``parse_fault(format_fault(f)) == f``)."""
    head: str = fault.kind
    options: list[str] = []
    if fault.sensor is not None:
        head = f"{'enc' if fault.sensor == 'encoders' else 'ft'}.{head}"
        if fault.joint is not None:
            options.append(f"joint={fault.joint}")
    elif fault.joint is not None:
        head = f"{fault.joint}.{head}"
    if fault.robot is not None:
        head = f"{fault.robot}:{head}"
    text = head
    if fault.value is not None:
        text += f"={_value_text(fault)}"
    trigger = ""
    if fault.random:
        if fault.rate is not None:
            trigger = f"rate {_num(fault.rate)}/s"
        else:
            trigger = f"p {_num(fault.probability or 0.0)} in {_num(fault.within)} s"
        if fault.when is not None:
            options.append(f"when={fault.when}")
        if fault.at is not None:
            options.append(f"at={_num(fault.at)} s")
    elif fault.when is not None:
        trigger = f"state {fault.when}" + (f"+{_num(fault.at)} s" if fault.at is not None else "")
    elif fault.at is not None:
        trigger = f"{_num(fault.at)} s"
    if trigger:
        text += f"@{trigger}"
    if fault.duration is not None:
        text += f" for {_num(fault.duration)} s"
    if fault.kind == "blow-up" and fault.mode != "nan":
        options.append(f"mode={fault.mode}")
    if fault.kind == "noise" or fault.kind == "bias":
        if fault.sensor == "ft" and fault.axis != "z":
            options.append(f"axis={fault.axis}")
    if fault.seed is not None:
        options.append(f"seed={fault.seed}")
    return ";".join([text, *options])
