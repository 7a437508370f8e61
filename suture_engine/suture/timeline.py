"""The knot held by the simulated thread at the end of each procedure state.

A run that ends with no knot tells little about where the knot was lost. This module
reads a recorded trace's ground truth (``/ground_truth/suture``, ``/ground_truth/tension``)
against its state changes (``/transitions``) and classifies the thread's centerline as it
was when each visited state ended, with the peak true tension during the state. It is
evaluation only, like the ground truth it reads: no skill sees it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from suture_engine.errors import SutureError
from suture_engine.trace.channels import GROUND_TRUTH_SUTURE, GROUND_TRUTH_TENSION, TRANSITIONS

__all__ = ["NoGroundTruth", "StateKnot", "knot_timeline"]


class NoGroundTruth(SutureError):
    """The trace holds no simulated thread (recorded on a backend without one).

    Attributes:
        path: the trace file.
    """

    code = "no-ground-truth"

    def __init__(self, path: str) -> None:
        super().__init__(
            f"{path}: no {GROUND_TRUTH_SUTURE} messages: the run had no simulated thread "
            "(use a backend with one, e.g. pybullet-surgical)"
        )
        self.path = path


@dataclass(frozen=True)
class StateKnot:
    """One visited state and the thread's knot when it ended.

    Attributes:
        state: the state's name (dotted inside a sub-procedure).
        start_s: simulation time the state was entered [s].
        end_s: simulation time it was left, or the trace's end [s].
        knot: the knot type of the last centerline recorded up to ``end_s``
            (``None`` when none was recorded yet).
        determinant: the knot determinant (1 for the unknot, 3 for a trefoil, 9 for a
            square or granny knot); ``None`` without a centerline.
        peak_tension_N: the largest true tension recorded during the state [N]
            (``None`` when none was).
    """

    state: str
    start_s: float
    end_s: float
    knot: str | None
    determinant: int | None
    peak_tension_N: float | None


def _centerline(data: dict[str, list[float]]) -> list[list[float]]:
    return [list(p) for p in zip(data["x"], data["y"], data["z"], strict=True)]


def knot_timeline(path: str | Path, *, seed: int = 0) -> Iterator[StateKnot]:
    """Classify the simulated thread at the end of every visited state of a trace.

    Args:
        path: a trace (``trace.mcap``) recorded with ground truth; a truncated one is
            read up to where it stops.
        seed: classifier seed.

    Yields:
        One :class:`StateKnot` per visited state, in order (a state visited twice gives
        two rows).

    Raises:
        TraceError: the trace cannot be read.
        NoGroundTruth: the trace has no simulated thread.
    """
    from suture_engine.suture.topology import classify_knot
    from suture_engine.trace.reader import TraceReader

    reader = TraceReader(path)
    if not reader.status.message_counts.get(GROUND_TRUTH_SUTURE):
        raise NoGroundTruth(str(path))
    state: str | None = None
    start = 0.0
    line: list[list[float]] | None = None
    peak: float | None = None
    t = 0.0

    def row(end: float) -> StateKnot:
        kind: str | None = None
        det: int | None = None
        if line is not None:
            report = classify_knot(line, seed=seed)
            kind, det = report.type, report.determinant
        return StateKnot(state or "(start)", start, end, kind, det, peak)

    for msg in reader.messages([TRANSITIONS, GROUND_TRUTH_SUTURE, GROUND_TRUTH_TENSION]):
        t = msg.log_time_ns * 1e-9
        if msg.topic == GROUND_TRUTH_SUTURE:
            line = _centerline(msg.data)
        elif msg.topic == GROUND_TRUTH_TENSION:
            value = float(msg.data["tension_N"])
            peak = value if peak is None else max(peak, value)
        else:
            if state is None:
                state = str(msg.data["source"])
            yield row(t)
            state, start, peak = str(msg.data["dest"]), t, None
    yield row(t)
