"""Compares two traces channel by channel, with explicit tolerances.

A golden comparison walks the expected and the actual messages of every
channel in order. Two messages match when their simulation times are equal
and every field matches: strings, booleans, integers and ``null`` exactly,
floats within the field's :class:`Tolerance` (``|actual - expected| <= abs +
rel * |expected|``), lists with equal lengths, objects with equal keys. Events,
transitions and operator events are compared exactly.

The result, :class:`GoldenResult`, says whether the traces match and, if not,
gives the first divergence in simulation time: tick, time, channel, field path,
expected and actual values and the tolerance, plus a readable text.

Example:
    >>> result = compare("tests/golden/hold.mcap", "runs/x/trace.mcap")
    >>> if not result.ok:
    ...     print(result.text)
"""

from __future__ import annotations

import fnmatch
import functools
import heapq
import math
import os
import re
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Union

from suture_engine.trace.reader import TraceMessage, TraceReader

__all__ = [
    "DEFAULT_TOLERANCES",
    "Divergence",
    "GoldenResult",
    "Tolerance",
    "ToleranceSpec",
    "compare",
]

_INDEX = re.compile(r"\[\d+\]")
_MISSING = "<missing>"


@dataclass(frozen=True)
class Tolerance:
    """The allowed difference of a numeric field.

    A value matches when ``|actual - expected| <= abs + rel * |expected|``.
    Two non-finite values (``null`` in JSON) match each other only.

    Attributes:
        abs: absolute tolerance [the field's unit].
        rel: relative tolerance [-].
    """

    abs: float = 0.0
    rel: float = 0.0

    def __post_init__(self) -> None:
        if not (self.abs >= 0.0 and self.rel >= 0.0):
            raise ValueError(f"tolerances must be >= 0, got abs={self.abs}, rel={self.rel}")

    def bound(self, expected: float) -> float:
        """The allowed ``|actual - expected|`` for this expected value."""
        return self.abs + self.rel * abs(expected)

    def allows(self, expected: float, actual: float) -> bool:
        """Whether ``actual`` matches ``expected``.

        Args:
            expected: the golden value [the field's unit].
            actual: the value to check [the field's unit].
        """
        return abs(actual - expected) <= self.bound(expected)

    def __str__(self) -> str:
        if self.abs == 0.0 and self.rel == 0.0:
            return "exact"
        return f"abs {self.abs:g} + rel {self.rel:g}"


EXACT = Tolerance()


@dataclass(frozen=True)
class ToleranceSpec:
    """Tolerances per channel and field, first matching rule wins.

    Attributes:
        rules: ``(topic_glob, field_glob, tolerance)`` triples. The field glob
            matches the field path without list indices (``position`` matches
            ``position[3]``; ``centerline`` matches ``centerline[4][2]``).
        ignore: ``(topic_glob, field_glob)`` pairs of fields not compared at all.
        default: the tolerance of numeric fields that no rule matches.
    """

    rules: tuple[tuple[str, str, Tolerance], ...] = ()
    ignore: tuple[tuple[str, str], ...] = ()
    default: Tolerance = EXACT

    def tolerance_for(self, topic: str, path: str) -> Tolerance | None:
        """The tolerance of a field, or ``None`` when it is ignored.

        Args:
            topic: the concrete topic (``/command/left``).
            path: the field path, with or without list indices (``values[3]``).
        """
        bare = _INDEX.sub("", path)
        for topic_glob, field_glob in self.ignore:
            if fnmatch.fnmatchcase(topic, topic_glob) and fnmatch.fnmatchcase(bare, field_glob):
                return None
        for topic_glob, field_glob, tol in self.rules:
            if fnmatch.fnmatchcase(topic, topic_glob) and fnmatch.fnmatchcase(bare, field_glob):
                return tol
        return self.default

    def with_rules(self, *rules: tuple[str, str, Tolerance]) -> ToleranceSpec:
        """A copy whose new rules take precedence over the existing ones."""
        return ToleranceSpec(tuple(rules) + self.rules, self.ignore, self.default)


DEFAULT_TOLERANCES = ToleranceSpec(
    rules=(
        ("/events", "*", EXACT),
        ("/transitions", "*", EXACT),
        ("/operator", "*", EXACT),
        ("/meta", "*", EXACT),
        ("/ground_truth/knot", "*", EXACT),
        ("/qp/*", "*", EXACT),
    ),
    ignore=(
        ("/meta", "engine_version"),
        ("/meta", "procedure_file"),
        ("/qp/*", "solve_time_us"),
    ),
    default=Tolerance(abs=1e-9, rel=1e-9),
)
"""Exact for events, transitions, operator events, metadata, knot and QP status;
``abs 1e-9 + rel 1e-9`` for other numbers (floating-point noise only). Ignores the
engine version, the procedure file's path (it depends on the checkout) and the
wall-clock QP solve time."""


@dataclass(frozen=True)
class Divergence:
    """The first place where two traces differ.

    Attributes:
        time_ns: simulation time of the message [ns].
        tick: the control tick (``time * control_rate``), or ``None`` without a rate.
        channel: the topic.
        index: the message's index on its channel (0-based).
        field: the field path (``values[3]``; ``""`` for the message itself).
        expected: the expected value (``"<missing>"`` when absent).
        actual: the actual value (``"<missing>"`` when absent).
        tolerance: the tolerance applied, or ``None`` for a structural difference.
        reason: what differs, in words.
    """

    time_ns: int
    tick: int | None
    channel: str
    index: int
    field: str
    expected: Any
    actual: Any
    tolerance: Tolerance | None
    reason: str


@dataclass(frozen=True)
class GoldenResult:
    """The outcome of a comparison.

    Attributes:
        ok: True when the traces match.
        divergence: the first divergence in simulation time, or ``None``.
        channel_divergences: the first divergence of every diverging channel.
        messages_compared: expected messages on the compared channels.
        channels_compared: channels compared.
    """

    ok: bool
    divergence: Divergence | None
    channel_divergences: tuple[Divergence, ...] = field(default=())
    messages_compared: int = 0
    channels_compared: int = 0

    def __bool__(self) -> bool:
        return self.ok

    @property
    def text(self) -> str:
        """A readable report of the comparison."""
        head = f"{self.messages_compared} messages on {self.channels_compared} channels"
        d = self.divergence
        if d is None:
            return f"traces match ({head})"
        tick = f"tick {d.tick}" if d.tick is not None else "tick ?"
        lines = [
            f"traces diverge: first at {tick} (t = {d.time_ns / 1e9:.9f} s)",
            f"  channel   {d.channel} (message #{d.index})",
            f"  field     {d.field or '<message>'}",
            f"  expected  {_show(d.expected)}",
            f"  actual    {_show(d.actual)}",
        ]
        if d.tolerance is not None and _is_float_pair(d.expected, d.actual):
            diff = abs(float(d.actual) - float(d.expected))
            bound = d.tolerance.bound(float(d.expected))
            lines.append(f"  |diff|    {diff:.6g} > {bound:.6g} ({d.tolerance})")
        lines.append(f"  reason    {d.reason}")
        others = [c for c in self.channel_divergences if c is not d]
        if others:
            lines.append(f"also diverging ({len(others)} more channels):")
            for c in others[:10]:
                where = c.field or "<message>"
                lines.append(
                    f"  {c.channel} from t = {c.time_ns / 1e9:.9f} s: {where} ({c.reason})"
                )
        lines.append(f"compared {head}")
        return "\n".join(lines)


TraceSource = Union[str, "os.PathLike[str]", TraceReader, Iterable[TraceMessage]]


def _stream(source: TraceSource) -> Iterable[TraceMessage]:
    if isinstance(source, (str, os.PathLike)):
        source = TraceReader(source)
    return source.messages() if isinstance(source, TraceReader) else source


class _Channel:
    """Per-topic state of a streaming comparison: unmatched messages of each side."""

    __slots__ = ("actual", "divergence", "expected", "n_actual", "n_expected")

    def __init__(self) -> None:
        self.expected: deque[TraceMessage] = deque()
        self.actual: deque[TraceMessage] = deque()
        self.n_expected = 0
        self.n_actual = 0
        self.divergence: Divergence | None = None


def compare(
    expected: TraceSource,
    actual: TraceSource,
    tolerances: ToleranceSpec = DEFAULT_TOLERANCES,
    *,
    topics: Sequence[str] | None = None,
    max_lag: int = 10_000,
) -> GoldenResult:
    """Compares an actual trace with an expected (golden) one.

    The n-th message of a channel is compared with the n-th message of the same
    channel on the other side. Both sides are read as streams merged in time order,
    so memory stays small whatever the length of the traces.

    Args:
        expected: the golden trace: a path, a reader, or messages in time order.
        actual: the trace to check: a path, a reader, or messages of a live run.
        tolerances: per-channel, per-field tolerances.
        topics: topics or globs to compare (default: every channel of either side).
        max_lag: a channel whose one side runs this many messages ahead of the
            other diverges there (bounds the memory).

    Returns:
        The result, with the first divergence in simulation time.

    Raises:
        TraceError: a file cannot be read (foreign, corrupt, I/O).
    """
    e_stream = ((m.log_time_ns, 0, i, m) for i, m in enumerate(_stream(expected)))
    a_stream = ((m.log_time_ns, 1, i, m) for i, m in enumerate(_stream(actual)))
    state: dict[str, _Channel] = {}
    selected: dict[str, bool] = {}
    rate: Any = None
    for _t, side, _i, msg in heapq.merge(e_stream, a_stream):
        topic = msg.topic
        if side == 0 and rate is None and topic == "/meta" and isinstance(msg.data, Mapping):
            rate = msg.data.get("control_rate_hz")
        keep = selected.get(topic)
        if keep is None:
            keep = topics is None or any(fnmatch.fnmatchcase(topic, p) for p in topics)
            selected[topic] = keep
        if not keep:
            continue
        ch = state.get(topic)
        if ch is None:
            ch = state[topic] = _Channel()
        if side == 0:
            ch.n_expected += 1
            if ch.divergence is None:
                ch.expected.append(msg)
        else:
            ch.n_actual += 1
            if ch.divergence is None:
                ch.actual.append(msg)
        if ch.divergence is not None:
            continue
        while ch.expected and ch.actual:
            index = ch.n_expected - len(ch.expected)
            d = _compare_pair(topic, index, ch.expected.popleft(), ch.actual.popleft(), tolerances)
            if d is not None:
                ch.divergence = d
                ch.expected.clear()
                ch.actual.clear()
                break
        if len(ch.expected) > max_lag or len(ch.actual) > max_lag:
            ch.divergence = _unmatched(topic, ch, f"more than {max_lag} messages apart")
    found: list[Divergence] = []
    for topic, ch in state.items():
        if ch.divergence is None and (ch.expected or ch.actual):
            ch.divergence = _unmatched(topic, ch, None)
        if ch.divergence is not None:
            found.append(replace(ch.divergence, tick=_tick(ch.divergence.time_ns, rate)))
    found.sort(key=lambda d: (d.time_ns, d.channel))
    first = found[0] if found else None
    messages = sum(ch.n_expected for ch in state.values())
    return GoldenResult(first is None, first, tuple(found), messages, len(state))


def _tick(time_ns: int, rate: Any) -> int | None:
    if not isinstance(rate, (int, float)) or rate <= 0:
        return None
    return round(time_ns * float(rate) / 1e9)


def _unmatched(topic: str, ch: _Channel, why: str | None) -> Divergence:
    """The divergence of a channel whose one side has messages the other lacks."""
    if ch.expected:
        e = ch.expected[0]
        index = ch.n_expected - len(ch.expected)
        reason = why or f"actual trace ends after {ch.n_actual} messages on this channel"
        return Divergence(e.log_time_ns, None, topic, index, "", e.data, _MISSING, None, reason)
    a = ch.actual[0]
    index = ch.n_actual - len(ch.actual)
    reason = why or f"unexpected message: expected only {ch.n_expected} on this channel"
    return Divergence(a.log_time_ns, None, topic, index, "", _MISSING, a.data, None, reason)


def _compare_pair(
    topic: str, index: int, e: TraceMessage, a: TraceMessage, spec: ToleranceSpec
) -> Divergence | None:
    if e.log_time_ns != a.log_time_ns:
        t = min(e.log_time_ns, a.log_time_ns)
        return Divergence(
            t,
            None,
            topic,
            index,
            "<time>",
            e.log_time_ns,
            a.log_time_ns,
            None,
            "messages at different simulation times [ns]",
        )
    if e.data == a.data:  # the common case, decided in C
        return None
    found = _diff(topic, "", e.data, a.data, spec)
    if found is None:
        return None
    path, ev, av, tol, reason = found
    return Divergence(e.log_time_ns, None, topic, index, path, ev, av, tol, reason)


@functools.lru_cache(maxsize=4096)
def _tolerance_cached(spec: ToleranceSpec, topic: str, bare: str) -> Tolerance | None:
    return spec.tolerance_for(topic, bare)


def _tolerance(spec: ToleranceSpec, topic: str, path: str) -> Tolerance | None:
    return _tolerance_cached(spec, topic, _INDEX.sub("", path))


_Found = tuple[str, Any, Any, Tolerance | None, str]


def _diff(topic: str, path: str, e: Any, a: Any, spec: ToleranceSpec) -> _Found | None:
    """The first difference inside two JSON values, or ``None``."""
    if isinstance(e, dict) and isinstance(a, dict):
        for key in sorted(set(e) | set(a)):
            sub = f"{path}.{key}" if path else str(key)
            if _tolerance(spec, topic, sub) is None:
                continue
            if key not in a:
                return sub, e[key], _MISSING, None, "field missing in the actual message"
            if key not in e:
                return sub, _MISSING, a[key], None, "unexpected field in the actual message"
            found = _diff(topic, sub, e[key], a[key], spec)
            if found is not None:
                return found
        return None
    if isinstance(e, list) and isinstance(a, list):
        if len(e) != len(a):
            return path, len(e), len(a), None, "lists of different lengths"
        for i, (ei, ai) in enumerate(zip(e, a, strict=True)):
            found = _diff(topic, f"{path}[{i}]", ei, ai, spec)
            if found is not None:
                return found
        return None
    if _is_float_pair(e, a):
        tol = _tolerance(spec, topic, path)
        if tol is None:
            return None
        ef, af = float(e), float(a)
        if isinstance(e, int) and isinstance(a, int) and tol == EXACT:
            return None if e == a else (path, e, a, tol, "values differ")
        if not (math.isfinite(ef) and math.isfinite(af)):
            return None if ef == af else (path, e, a, tol, "non-finite value")
        if tol.allows(ef, af):
            return None
        return path, e, a, tol, "outside the tolerance"
    if type(e) is not type(a):
        return path, e, a, None, f"types differ ({type(e).__name__} vs {type(a).__name__})"
    if e != a:
        return path, e, a, EXACT, "values differ"
    return None


def _is_float_pair(e: Any, a: Any) -> bool:
    return (
        isinstance(e, (int, float))
        and isinstance(a, (int, float))
        and not isinstance(e, bool)
        and not isinstance(a, bool)
    )


def _show(value: Any) -> str:
    if isinstance(value, str) and value == _MISSING:
        return value
    text = repr(value)
    return text if len(text) <= 200 else text[:197] + "..."
