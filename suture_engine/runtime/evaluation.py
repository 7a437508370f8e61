"""A run's evaluation for ``summary.json``: knots and STAR-style stitch metrics.

Everything here is computed from what a run records for evaluation (the
backend's ground truth: the suture's centerline and true tension; the
estimated tension), never from the procedure's own belief, and never shown
to skills.

- **Bites.** The centerline dips under the tissue surface where a stitch
  passes through it. A bite is a maximal run of centerline points more than
  ``min_depth`` under the tissue plane (through ``tissue_point``, normal
  ``tissue_normal``) that crosses the wound line when one is given (a thread
  hanging below the plane beyond the tissue is not a bite, nor is one lying in the
  wound's opening, both pierce points within ``IN_WOUND`` of the line, nor one going into
  it, a pierce point within ``IN_OPENING``); its pierce
  points are where the centerline crosses the plane just before and after
  the run (linear interpolation), and its depth
  is the run's largest distance under the plane. Along the centerline (tail
  first) the first pierce point is the entry, the second the exit; when the
  declared points say the other way round fits better, they are swapped.
  These are the thread's pierce points: the needle drew the thread through
  them, the simulator records no needle-tip path.
- **Stitch metrics** (as in STAR's suture evaluation): per bite the distance
  of the entry and exit pierce points from the scene's declared entry/exit
  points (the nearest declared pair, ``entry_k``/``exit_k``), the bite depth,
  and the spacing between consecutive bites' centres, mean +- SD, each with its
  resolution: a pierce point is interpolated between two centerline points (one per
  capsule on the simulated thread, about 3.5 mm apart), so it can lie up to that
  segment's length from where the thread crosses (``*_resolution_mm``).
- **Knots.** One entry per stitch when there are several bites: the
  centerline is cut at the arc-length midpoints between consecutive bites
  and each piece is classified on its own (the knot tying stitch k binds the
  strands on either side of bite k); otherwise one entry for the whole
  centerline. Each entry: the classifier's topology (``type``,
  ``determinant``, ``v2``, ``v3``, ...), ``seated`` (knot centre on the
  tissue plane, :func:`suture_engine.suture.geometry.knot_summary`) and
  ``post_straight`` with its ``lay`` from
  :func:`suture_engine.suture.knot.knot_lay` (True: square lay; False: two
  half hitches, thesis Fig. 7.4), and ``through_tissue``: whether the thread of the
  entry still passes through the tissue (has a bite). A knot whose thread has come out
  of the tissue binds no stitch: it is tied, but it is not a surgical knot.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "IN_OPENING",
    "IN_WOUND",
    "Bite",
    "TraceEvaluation",
    "evaluate",
    "evaluate_trace",
    "find_bites",
    "knot_entries",
    "stitch_metrics",
    "tension_metrics",
]

FloatArray = NDArray[np.float64]

MIN_DEPTH = 5e-5
"""Depth under the tissue plane [m] below which centerline points count as inside. Small:
the thread's axis lies a contact radius (0.9 mm) above the pad wherever it rests on it, so
a point under the plane and over the wound is in the tissue; a stitched start's channel is
0.5 mm deep and a taut thread in it runs 0.1-0.2 mm under the surface."""


IN_WOUND = 1e-3
"""Distance from the wound line [m] within which a passage's two plane crossings show the
thread lying in the wound's opening, not a bite. A simulated thread resting across the
PyBullet pad's 1 mm slit sags into it: on a registered run of algorithm 3 one centerline
point lay 0.09 mm under the plane there, its crossings 0.06 and 0.04 mm from the line, and
was counted as a second bite, which cut the square knot into two unknotted pieces."""

IN_OPENING = 0.5e-3
"""Distance from the wound line [m] within which one plane crossing shows the thread going
into the plane through the wound's opening (half the PyBullet pad's 1 mm slit), not
through tissue: a passage with such a crossing is not a bite. A single throw's tail sagged
in from 2.59 mm out to 0.17 mm past the line, and a square drawn 2.66 mm down into the
slit went in 3.32 mm out and came out 0.34 mm past it; each was counted as a second bite
and cut its knot into unknotted pieces. The bites' own crossings lie further out but not
far: on 187 stored runs of algorithm 3, each bite's nearer crossing lay 0.84-4.0 mm from
the line (the bundled scenes' points are 4 mm out; the thread's centerline, one point per
3.5 mm capsule, puts an interpolated crossing up to 3 mm nearer). The margin is thin on
both sides: a finer centerline would widen it."""


class Bite(NamedTuple):
    """One passage of the thread through the tissue.

    Attributes:
        entry: pierce point where the thread goes in, world frame [m].
        exit: pierce point where it comes out, world frame [m].
        depth: largest distance of the thread under the tissue plane [m].
        first: index of the first centerline point under the plane.
        last: index of the last centerline point under the plane.
        entry_span: length of the centerline segment the entry was interpolated on [m]
            (the distance between the two points either side of the plane). The thread
            crosses the plane somewhere on its piece between those two points, and the
            pierce point lies on the chord between them, so for a straight piece it lies
            at most this far from the thread's own crossing (a bent piece: at most the
            piece's length): the measure's resolution, not an error of the stitch. NaN
            when not known.
        exit_span: the same for the exit [m].
    """

    entry: tuple[float, float, float]
    exit: tuple[float, float, float]
    depth: float
    first: int
    last: int
    entry_span: float = math.nan
    exit_span: float = math.nan


def _points(centerline: ArrayLike) -> FloatArray:
    pts = np.asarray(centerline, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise ValueError(f"a centerline is a finite N x 3 array, got shape {pts.shape}")
    return pts


def _crossing(a: FloatArray, b: FloatArray, ha: float, hb: float) -> tuple[float, float, float]:
    s = ha / (ha - hb) if ha != hb else 0.5
    p = a + s * (b - a)
    return (float(p[0]), float(p[1]), float(p[2]))


def _crosses_wound(
    bite: Bite,
    wound: tuple[ArrayLike, ArrayLike],
    normal: FloatArray,
    margin: float,
    in_wound: float,
    opening: float,
) -> bool:
    """Whether the bite's entry and exit lie on either side of the wound line, beside it,
    not both within ``in_wound`` [m] of it (the thread lying in the wound's opening), and
    neither within ``opening`` [m] of it (the thread going into or out of the plane through
    the opening, not through tissue)."""
    a, b = np.asarray(wound[0], dtype=float), np.asarray(wound[1], dtype=float)
    along = b - a
    length = float(np.linalg.norm(along))
    if length < 1e-12:
        return True
    along = along / length
    side = np.cross(normal, along)  # in the surface, across the wound
    e, x = np.asarray(bite.entry) - a, np.asarray(bite.exit) - a
    de, dx = float(e @ side), float(x @ side)
    if de * dx > 0.0:
        return False
    if abs(de) <= in_wound and abs(dx) <= in_wound:
        return False
    if min(abs(de), abs(dx)) <= opening:
        return False
    s = de / (de - dx) if de != dx else 0.5
    where = float((e + s * (x - e)) @ along)
    return -margin <= where <= length + margin


def find_bites(
    centerline: ArrayLike,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    min_depth: float = MIN_DEPTH,
    wound: tuple[ArrayLike, ArrayLike] | None = None,
    wound_margin: float = 5e-3,
    in_wound: float = IN_WOUND,
    opening: float = IN_OPENING,
) -> list[Bite]:
    """The thread's passages through the tissue, in order along the centerline.

    Args:
        centerline: N x 3 suture centerline, world frame [m].
        tissue_point: a point of the tissue surface [m].
        tissue_normal: the surface's outward normal (normalised here).
        min_depth: depth under the plane that counts as inside [m].
        wound: the wound line's two ends [m]: when given, a bite counts only if it
            crosses the wound (entry and exit on either side of it, within its length
            plus ``wound_margin``); a thread hanging below the surface plane beyond the
            tissue is not a bite.
        wound_margin: how far beyond the wound's ends a crossing still counts [m].
        in_wound: with ``wound``: a passage whose entry and exit both lie within this of
            the wound line [m] is the thread lying in the wound's opening, not a bite
            (:data:`IN_WOUND`).
        opening: with ``wound``: a passage whose entry or exit lies within this of the
            wound line [m] goes into the plane through the wound's opening, not through
            tissue: not a bite (:data:`IN_OPENING`).

    Returns:
        The complete bites (a run reaching an end of the centerline has no exit and
        is left out).
    """
    pts = _points(centerline)
    n = np.asarray(tissue_normal, dtype=float)
    n = n / np.linalg.norm(n)
    h = (pts - np.asarray(tissue_point, dtype=float)) @ n
    inside = h < -min_depth
    bites: list[Bite] = []
    k = 0
    while k < len(pts):
        if not inside[k]:
            k += 1
            continue
        first = k
        while k < len(pts) and inside[k]:
            k += 1
        last = k - 1
        # the plane crossings around the run: walk out to the last point above the plane
        i = first
        while i > 0 and h[i - 1] < 0.0:
            i -= 1
        j = last
        while j < len(pts) - 1 and h[j + 1] < 0.0:
            j += 1
        # One passage runs from plane crossing to plane crossing: a point in it that
        # rises above min_depth without leaving the plane does not split it in two (the
        # two runs would share both crossings, and the knot would be cut between them).
        k = j + 1
        if i == 0 or j == len(pts) - 1:
            continue
        last = first + int(np.flatnonzero(inside[first : j + 1])[-1])
        entry = _crossing(pts[i - 1], pts[i], float(h[i - 1]), float(h[i]))
        exit_ = _crossing(pts[j], pts[j + 1], float(h[j]), float(h[j + 1]))
        bite = Bite(
            entry,
            exit_,
            float(-h[first : last + 1].min()),
            first,
            last,
            float(np.linalg.norm(pts[i] - pts[i - 1])),
            float(np.linalg.norm(pts[j + 1] - pts[j])),
        )
        if wound is None or _crosses_wound(bite, wound, n, wound_margin, in_wound, opening):
            bites.append(bite)
    return bites


def _declared_pairs(
    points: Mapping[str, Sequence[float]],
) -> list[tuple[str, FloatArray, FloatArray]]:
    """``(suffix, entry, exit)`` for every declared ``entry<s>`` with an ``exit<s>``."""
    out = []
    for name, value in points.items():
        if not name.startswith("entry"):
            continue
        suffix = name[len("entry") :]
        other = points.get("exit" + suffix)
        if other is not None:
            out.append(
                (suffix.lstrip("_"), np.asarray(value, dtype=float), np.asarray(other, float))
            )
    return out


def _mean_sd(values: Sequence[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    arr = np.asarray(values, dtype=float)
    sd = float(arr.std(ddof=1)) if len(arr) > 1 else 0.0
    return float(arr.mean()), sd


def _mm(value: float) -> float | None:
    return round(1e3 * value, 4) if math.isfinite(value) else None


def stitch_metrics(
    bites: Sequence[Bite], declared: Mapping[str, Sequence[float]] | None = None
) -> dict[str, Any]:
    """STAR-style metrics of the bites (see the module docstring), JSON-ready, in mm.

    Args:
        bites: the bites, in order along the thread.
        declared: the scene's named tissue points (``entry``/``exit`` or
            ``entry_k``/``exit_k``) [m]; None: no position errors.

    Returns:
        ``count``; per bite (lists, in order) ``entry_error_mm``, ``exit_error_mm``,
        ``bite_depth_mm`` and the matched ``site`` ("" for ``entry``/``exit``, else the
        suffix); ``spacing_mean_mm`` and ``spacing_sd_mm`` between consecutive bite
        centres (None with fewer than two bites). Each figure comes with the
        measure's resolution: ``entry_resolution_mm`` and ``exit_resolution_mm`` per
        bite, the length of the centerline segment that pierce point was interpolated
        on (:attr:`Bite.entry_span`; a bound on how far it can lie from where the
        thread crosses, so an error under it is not resolved), and
        ``spacing_resolution_mm``, the largest bound on one spacing (half of each
        pierce point's span, summed over the two bites' four; None with fewer than
        two bites). When the declared points fit a bite the other way round, its
        entry figures are its exit's.
    """
    pairs = _declared_pairs(declared or {})
    entry_err: list[float | None] = []
    exit_err: list[float | None] = []
    entry_res: list[float | None] = []
    exit_res: list[float | None] = []
    sites: list[str | None] = []
    for b in bites:
        e, x = np.asarray(b.entry), np.asarray(b.exit)
        best: tuple[float, float, str, bool] | None = None
        for suffix, pe, px in pairs:
            straight = (float(np.linalg.norm(e - pe)), float(np.linalg.norm(x - px)), False)
            swapped = (float(np.linalg.norm(x - pe)), float(np.linalg.norm(e - px)), True)
            for de, dx, flip in (straight, swapped):
                if best is None or de + dx < best[0] + best[1]:
                    best = (de, dx, suffix, flip)
        flipped = best is not None and best[3]
        entry_res.append(_mm(b.exit_span if flipped else b.entry_span))
        exit_res.append(_mm(b.entry_span if flipped else b.exit_span))
        if best is None:
            entry_err.append(None)
            exit_err.append(None)
            sites.append(None)
        else:
            entry_err.append(round(1e3 * best[0], 4))
            exit_err.append(round(1e3 * best[1], 4))
            sites.append(best[2])
    centres = [0.5 * (np.asarray(b.entry) + np.asarray(b.exit)) for b in bites]
    spacing = [float(np.linalg.norm(b - a)) * 1e3 for a, b in itertools.pairwise(centres)]
    # a centre is the mean of two pierce points: it can lie half of each one's span off
    centre_bound = [0.5 * (b.entry_span + b.exit_span) for b in bites]
    spacing_bound = [a + b for a, b in itertools.pairwise(centre_bound)]
    # NaN (a span not known) makes max() order-dependent: no bound then
    worst = max(spacing_bound, default=math.nan)
    if not all(map(math.isfinite, spacing_bound)):
        worst = math.nan
    mean, sd = _mean_sd(spacing)
    return {
        "count": len(bites),
        "site": sites,
        "entry_error_mm": entry_err,
        "exit_error_mm": exit_err,
        "entry_resolution_mm": entry_res,
        "exit_resolution_mm": exit_res,
        "bite_depth_mm": [round(1e3 * b.depth, 4) for b in bites],
        "spacing_mean_mm": None if mean is None else round(mean, 4),
        "spacing_sd_mm": None if sd is None else round(sd, 4),
        "spacing_resolution_mm": _mm(worst) if spacing_bound else None,
    }


def tension_metrics(
    estimated: Iterable[float],
    true: Iterable[float] | None = None,
    true_peak_at: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Peak and final tension [N] of the estimate and, when simulated, of the thread.

    Args:
        estimated: the recorded estimated tension, in time order [N].
        true: the thread's true tension in time order [N] (None: no thread).
        true_peak_at: where the true peak was reached, given as
            ``peak_true_tension_at``: ``t_s`` [s] simulated, ``state`` (the automaton's
            state then) and ``joint`` (the joint it acted at, an index among the
            ground-truth centerline's points; None when the backend does not say).
            None: not known.
    """

    def peak_final(values: Iterable[float] | None) -> tuple[float | None, float | None]:
        peak: float | None = None
        last: float | None = None
        for v in values or ():
            if not math.isfinite(v):
                continue
            last = float(v)
            peak = last if peak is None else max(peak, last)
        return peak, last

    pe, fe = peak_final(estimated)
    pt, ft = peak_final(true)
    return {
        "peak_tension_N": pe,
        "final_tension_N": fe,
        "peak_true_tension_N": pt,
        "final_true_tension_N": ft,
        "peak_true_tension_at": None if true_peak_at is None else dict(true_peak_at),
    }


def _pieces(pts: FloatArray, bites: Sequence[Bite]) -> list[FloatArray]:
    """The centerline cut at the arc-length midpoints between consecutive bites."""
    if len(bites) < 2:
        return [pts]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    cuts = [0]
    for a, b in itertools.pairwise(bites):
        middle = 0.5 * (arc[a.last] + arc[b.first])
        cuts.append(int(np.searchsorted(arc, middle)))
    cuts.append(len(pts))
    return [pts[c0 : max(c1 + 1, c0 + 2)] for c0, c1 in itertools.pairwise(cuts)]


def knot_entries(
    centerline: ArrayLike,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    contact_diameter: float | None,
    bites: Sequence[Bite] | None = None,
) -> list[dict[str, Any]]:
    """One knot entry per stitch (see the module docstring).

    Args:
        centerline: N x 3 ground-truth centerline [m].
        tissue_point: a point of the tissue surface [m].
        tissue_normal: the surface's outward normal.
        contact_diameter: the simulated thread's contact diameter [m] for
            ``post_straight`` (None: ``post_straight`` is null, with a reason).
        bites: the bites (None: found here).

    Returns:
        The entries, in order along the thread (one when there are fewer than two
        bites); an entry that cannot be classified carries ``type`` None and ``error``.
    """
    from suture_engine.errors import SutureError
    from suture_engine.suture.geometry import knot_summary
    from suture_engine.suture.knot import knot_lay

    pts = _points(centerline)
    if bites is None:
        bites = find_bites(pts, tissue_point, tissue_normal)
    out: list[dict[str, Any]] = []
    for k, piece in enumerate(_pieces(pts, bites)):
        try:
            entry = dict(
                knot_summary(piece, tissue_point=tissue_point, tissue_normal=tissue_normal)
            )
        except (SutureError, ValueError) as exc:  # a degenerate piece
            entry = {"type": None, "error": str(exc)}
        if len(bites) > 1:
            entry["stitch"] = k + 1
        # every piece holds one bite when there are several; a single piece holds them all
        entry["through_tissue"] = len(bites) > 0
        if entry.get("type") in (None, "unknot"):
            # no knot to lie square or as half hitches: strands that merely touch are not a lay
            entry["post_straight"] = None
            entry["post_straight_reason"] = "no knot in this stitch's thread"
        elif contact_diameter is None:
            entry["post_straight"] = None
            entry["post_straight_reason"] = "the backend gives no thread contact diameter"
        else:
            try:
                lay = knot_lay(piece, diameter=contact_diameter)
                entry["post_straight"] = lay.post_straight
                entry["lay"] = lay.lay
            except ValueError as exc:
                entry["post_straight"] = None
                entry["post_straight_reason"] = str(exc)
        out.append(entry)
    return out


class TraceEvaluation(NamedTuple):
    """What :func:`evaluate_trace` finds in a trace.

    Attributes:
        knot: one knot entry (a dict) or several (a list), None without a centerline.
        metrics: ``stitches`` (:func:`stitch_metrics`, None without a centerline) and
            the tension figures of :func:`tension_metrics`.
    """

    knot: dict[str, Any] | list[dict[str, Any]] | None
    metrics: dict[str, Any]


def _centerline(message: Mapping[str, Any]) -> FloatArray | None:
    if "centerline" in message:
        return np.asarray(message["centerline"], dtype=float)
    if {"x", "y", "z"} <= set(message):
        return np.column_stack([message["x"], message["y"], message["z"]]).astype(float)
    return None


def evaluate(
    centerline: ArrayLike | None,
    estimated: Iterable[float],
    true: Iterable[float] | None,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    declared: Mapping[str, Sequence[float]] | None = None,
    contact_diameter: float | None = None,
    wound: tuple[ArrayLike, ArrayLike] | None = None,
    cut: Sequence[ArrayLike] = (),
    true_peak_at: Mapping[str, Any] | None = None,
) -> TraceEvaluation:
    """Knots and metrics from a final centerline and tension series (see the module).

    With ``cut`` threads (an interrupted suture's, one per stitch) every thread is
    evaluated on its own and ``knot`` is a list with one entry per thread's knot, in
    their order along the wound: ``stitch`` (1, 2, ... along the wound), ``thread`` (1 for
    the first thread loaded, ...) and ``cut`` (whether the thread was cut); the stitch
    metrics take the bites of all threads, in that order.

    Args:
        centerline: N x 3 ground-truth centerline [m] (None: no thread).
        estimated: estimated tension series [N].
        true: the thread's true tension series [N] (None: no thread).
        tissue_point: a point of the tissue surface [m].
        tissue_normal: the surface's outward normal.
        declared: the scene's named tissue points [m].
        contact_diameter: the simulated thread's contact diameter [m].
        wound: the wound line's ends [m]; bites must cross it (see :func:`find_bites`).
        cut: the centerlines of the threads cut before the last one [m], in the order
            they were cut.
        true_peak_at: where the true tension peaked (see :func:`tension_metrics`).
    """
    metrics: dict[str, Any] = dict(tension_metrics(estimated, true, true_peak_at))
    threads = [_points(c) for c in cut]
    if centerline is not None:
        threads.append(_points(centerline))
    if not threads:
        metrics["stitches"] = None
        return TraceEvaluation(None, metrics)
    if len(threads) == 1:
        pts = threads[0]
        bites = find_bites(pts, tissue_point, tissue_normal, wound=wound)
        metrics["stitches"] = stitch_metrics(bites, declared)
        entries = knot_entries(pts, tissue_point, tissue_normal, contact_diameter, bites)
        knot: dict[str, Any] | list[dict[str, Any]] = entries[0] if len(entries) == 1 else entries
        return TraceEvaluation(knot, metrics)
    # An interrupted suture: one thread per stitch, each evaluated on its own, in their
    # order along the wound (the order they were loaded in is ``thread``).
    found = []
    for order, pts in enumerate(threads):
        bites = find_bites(pts, tissue_point, tissue_normal, wound=wound)
        found.append((_along_wound(bites, wound), order, pts, bites))
    found.sort(key=lambda item: (item[0], item[1]))
    all_bites = [b for _, _, _, bites in found for b in bites]
    metrics["stitches"] = stitch_metrics(all_bites, declared)
    entries = []
    for _, order, pts, bites in found:
        for entry in knot_entries(pts, tissue_point, tissue_normal, contact_diameter, bites):
            entry["stitch"] = len(entries) + 1
            entry["thread"] = order + 1
            entry["cut"] = order < len(cut)
            entries.append(entry)
    return TraceEvaluation(entries, metrics)


def _along_wound(bites: Sequence[Bite], wound: tuple[ArrayLike, ArrayLike] | None) -> float:
    """Where a thread's bites lie along the wound [m] (their centres' mean, projected on
    the wound line from its start); +inf without a bite, 0 without a wound."""
    if not bites:
        return math.inf
    if wound is None:
        return 0.0
    a, b = np.asarray(wound[0], dtype=float), np.asarray(wound[1], dtype=float)
    along = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)
    centres = [0.5 * (np.asarray(x.entry) + np.asarray(x.exit)) for x in bites]
    return float(np.mean([(c - a) @ along for c in centres]))


def _number(value: Any) -> float:
    """A trace's number: a non-finite value is written as null; read back as NaN."""
    return math.nan if value is None else float(value)


def evaluate_trace(
    path: str | Path,
    tissue_point: ArrayLike,
    tissue_normal: ArrayLike,
    declared: Mapping[str, Sequence[float]] | None = None,
    contact_diameter: float | None = None,
    wound: tuple[ArrayLike, ArrayLike] | None = None,
) -> TraceEvaluation:
    """Evaluate a recorded trace: its last ``/ground_truth/suture`` centerline, its
    ``/ground_truth/tension`` and ``/tension/estimated`` series, and the cut threads'
    centerlines on ``/ground_truth/suture_cut``.

    Args:
        path: the trace file.
        tissue_point: a point of the tissue surface [m].
        tissue_normal: the surface's outward normal.
        declared: the scene's named tissue points [m].
        contact_diameter: the simulated thread's contact diameter [m].
        wound: the wound line's ends [m] (see :func:`find_bites`).

    Raises:
        TraceError: the trace cannot be read.
    """
    from suture_engine.trace import channels
    from suture_engine.trace.reader import TraceReader

    topics = [channels.GROUND_TRUTH_SUTURE, channels.GROUND_TRUTH_TENSION]
    topics += [channels.TENSION_ESTIMATED, channels.GROUND_TRUTH_SUTURE_CUT]
    topics += [channels.TRANSITIONS]
    centerline: FloatArray | None = None
    cut: list[FloatArray] = []
    estimated: list[float] = []
    true: list[float] = []
    state = ""
    peak, peak_at = -math.inf, None
    for msg in TraceReader(path).messages(topics):
        if msg.topic == channels.TRANSITIONS:
            state = str(msg.data.get("dest", state))
        elif msg.topic == channels.GROUND_TRUTH_SUTURE:
            centerline = _centerline(msg.data) if msg.data else centerline
        elif msg.topic == channels.GROUND_TRUTH_SUTURE_CUT:
            line = _centerline(msg.data) if msg.data else None
            if line is not None:
                cut.append(line)
            centerline = None  # the thread after the cut is the next one
        elif msg.topic == channels.GROUND_TRUTH_TENSION:
            value = _number(msg.data["tension_N"])
            if value > peak:  # false for NaN
                peak = value
                joint = msg.data.get("joint")
                peak_at = {
                    "t_s": msg.log_time_ns * 1e-9,
                    "state": state,
                    "joint": None if joint is None else int(joint),
                }
            true.append(value)
        else:
            estimated.append(_number(msg.data["tension_N"]))
    return evaluate(
        centerline,
        estimated,
        true if true else None,
        tissue_point,
        tissue_normal,
        declared,
        contact_diameter,
        wound,
        cut,
        peak_at if true else None,
    )
