"""When each fault is active: its trigger turned into onsets, tick by tick.

A fault's *anchor* is tick 0, or the first tick its ``when`` state is seen
running. From the anchor its onsets follow (ticks of the control period ``dt``):

- timed: one onset ``at`` after the anchor, lasting ``duration`` (or to the end);
- ``probability``: one onset with that probability, at ``at + U(0, within)``;
- ``rate``: a Poisson process from ``at`` on: exponential gaps of mean
  ``1/rate``, each onset lasting ``duration`` (default 10 ms).

Each fault draws from its own stream, ``numpy.random.SeedSequence([seed, index])``
(``seed`` is the fault's own or the run's), so the same seed gives the same
onsets, whatever the other faults do. The same stream's second child feeds the
sensor noise (:meth:`FaultSchedule.noise_rng`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from suture_engine.faults.model import Fault

__all__ = ["FaultSchedule", "Onset", "state_matches"]


@dataclass(frozen=True)
class Onset:
    """One occurrence of a fault.

    Attributes:
        index: the fault's index in the run's list.
        fault: the fault.
        start: first tick it is active.
        end: first tick it is no longer active (None: to the end of the run).
        occurrence: 0 for the first onset of this fault, 1 for the next, ...
    """

    index: int
    fault: Fault
    start: int
    end: int | None
    occurrence: int

    def active(self, tick: int) -> bool:
        """True while ``start <= tick < end``."""
        return self.start <= tick and (self.end is None or tick < self.end)


def state_matches(state: str | None, name: str) -> bool:
    """True when the running step ``state`` is ``name`` (or ends with ``.name``, a step of
    a sub-procedure, e.g. ``mirrored-knot.tighten`` for ``tighten``)."""
    if not state:
        return False
    return state == name or state.endswith("." + name)


class _Stream:
    """One fault's trigger state and random stream."""

    def __init__(self, index: int, fault: Fault, seed: int) -> None:
        self.index = index
        self.fault = fault
        children = np.random.SeedSequence(
            [int(fault.seed if fault.seed is not None else seed), index]
        ).spawn(2)
        self.rng = np.random.default_rng(children[0])
        self.noise = np.random.default_rng(children[1])
        self.anchor: int | None = None
        self.next_start: int | None = None
        self.count = 0
        self.done = False


class FaultSchedule:
    """The onsets of a list of faults, advanced one tick at a time.

    Args:
        faults: the faults, in order (their index is their position).
        seed: the run's seed (used by faults without their own).
        dt: the control period [s].
    """

    def __init__(self, faults: Sequence[Fault], seed: int, dt: float) -> None:
        self.faults = tuple(faults)
        self.dt = float(dt)
        self._streams = [_Stream(i, f, seed) for i, f in enumerate(self.faults)]
        self.active: list[Onset] = []
        self.tick = -1

    def _ticks(self, seconds: float) -> int:
        return round(seconds / self.dt)

    def noise_rng(self, index: int) -> Any:
        """The noise generator of fault ``index`` (a numpy Generator)."""
        return self._streams[index].noise

    def _first_start(self, s: _Stream, anchor: int) -> int | None:
        f = s.fault
        at = f.at or 0.0
        if f.probability is not None:
            if s.rng.random() >= f.probability:
                return None
            return anchor + self._ticks(at + s.rng.uniform(0.0, f.within))
        if f.rate is not None:
            return anchor + self._ticks(at + s.rng.exponential(1.0 / f.rate))
        return anchor + self._ticks(at)

    def update(self, tick: int, state: str | None = None) -> tuple[list[Onset], list[Onset]]:
        """Advance to ``tick`` (the running step ``state``); return (started, ended) onsets.

        Args:
            tick: the measurement's tick (increasing).
            state: the step running at this tick (None: no step), for ``when`` triggers.
        """
        self.tick = tick
        ended = [o for o in self.active if not o.active(tick)]
        if ended:
            self.active = [o for o in self.active if o.active(tick)]
        started: list[Onset] = []
        for s in self._streams:
            if s.done:
                continue
            f = s.fault
            if s.anchor is None:
                if f.when is None or state_matches(state, f.when):
                    s.anchor = tick
                    s.next_start = self._first_start(s, tick)
                    if s.next_start is None:
                        s.done = True
                        continue
                else:
                    continue
            while s.next_start is not None and s.next_start <= tick:
                duration = f.default_duration
                end = None if duration is None else s.next_start + max(1, self._ticks(duration))
                onset = Onset(s.index, f, s.next_start, end, s.count)
                s.count += 1
                if onset.active(tick):
                    started.append(onset)
                    self.active.append(onset)
                if f.rate is not None:
                    s.next_start += max(1, self._ticks(s.rng.exponential(1.0 / f.rate)))
                else:
                    s.next_start = None
                    s.done = True
        return started, ended
