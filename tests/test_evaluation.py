"""A run's evaluation (knots per stitch, STAR-style stitch metrics) on hand-built threads.

Oracles: centerlines built here from known pieces (bites of known pierce points
and depth, the classifier-verified hand-built knots of
:mod:`suture_engine.suture.curves`), and traces written with the trace writer
around :func:`suture_engine.trace.synthetic.synthetic_messages`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from suture_engine.runtime.evaluation import (
    evaluate,
    evaluate_trace,
    find_bites,
    knot_entries,
    stitch_metrics,
    tension_metrics,
)
from suture_engine.suture import curves

MM = 1e-3
NORMAL = (0.0, 0.0, 1.0)
SURFACE = (0.0, 0.0, 0.0)


def _bite(x: float, depth: float, half_width: float = 4 * MM, n: int = 41) -> np.ndarray:
    """Through the tissue along +y at x: in at (x, -w, 0), out at (x, +w, 0), depth at y = 0."""
    y = np.linspace(-half_width, half_width, n)
    z = -depth * np.sin(np.pi * (y + half_width) / (2 * half_width))
    return np.c_[np.full(n, x), y, z]


def _knot(kind: str | None, start: np.ndarray) -> np.ndarray:
    """A hand-built knot (0.5 mm per unit) laid along x above the tissue, from ``start``."""
    if kind is None:
        return start + np.array([[0.0, 0.0, 3 * MM], [10 * MM, 0.0, 3 * MM]])
    shape = {"square": curves.square_knot, "granny": curves.granny_knot}[kind]() * 0.5 * MM
    shape = shape - shape[0] + start + np.array([0.0, 0.0, 3 * MM])  # knot z in [-1, 3] units above
    return shape


def _thread(sites: list[tuple[float, float, str | None]]) -> np.ndarray:
    """Tail on the surface, then per stitch: bite, knot, a long detour to the next bite."""
    parts = [np.array([[sites[0][0] - 10 * MM, -4 * MM, 1 * MM]])]
    for k, (x, depth, kind) in enumerate(sites):
        parts.append(_bite(x, depth))
        knot = _knot(kind, np.array([x, 8 * MM, 0.0]))
        parts.append(np.array([[x, 6 * MM, 2 * MM]]))
        parts.append(knot)
        end = knot[-1]
        nxt = sites[k + 1][0] if k + 1 < len(sites) else x + 10 * MM
        # up high and back: a connector longer than any knot, so the cut lands in it
        parts.append(
            np.array(
                [
                    [end[0], 30 * MM, 5 * MM],
                    [end[0], 30 * MM, 150 * MM],
                    [nxt, -30 * MM, 150 * MM],
                    [nxt, -30 * MM, 5 * MM],
                    [nxt, -6 * MM, 1 * MM],
                ]
            )
        )
    return np.vstack(parts)


LAYS = ("square", "half-hitches", "undetermined", "no-knot")
SITES = [(-5 * MM, 2.0 * MM, "square"), (0.0, 3.0 * MM, None), (6 * MM, 2.5 * MM, "granny")]


def test_bites_are_found_with_their_pierce_points_and_depth() -> None:
    bites = find_bites(_thread(SITES), SURFACE, NORMAL)
    assert len(bites) == 3
    for b, (x, depth, _) in zip(bites, SITES, strict=True):
        np.testing.assert_allclose(b.entry, (x, -4 * MM, 0.0), atol=1e-12)
        np.testing.assert_allclose(b.exit, (x, 4 * MM, 0.0), atol=1e-12)
        assert b.depth == pytest.approx(depth, rel=1e-12)


def test_pierce_points_interpolate_between_samples_on_a_tilted_plane() -> None:
    # a bite whose samples straddle the plane: the crossing is the linear interpolation
    pts = np.array([[0.0, -2.0, 1.0], [0.0, 0.0, -1.0], [0.0, 1.0, -1.0], [0.0, 3.0, 3.0]]) * MM
    tilt = np.array([0.0, 0.6, 0.8])  # plane through the origin, tilted about x
    rot = np.array([[1.0, 0.0, 0.0], [0.0, 0.8, -0.6], [0.0, 0.6, 0.8]])  # e_z -> tilt
    assert rot.T @ np.array([0, 0, 1.0]) == pytest.approx(tilt)
    bites = find_bites(pts @ rot, SURFACE, tilt)
    assert len(bites) == 1
    np.testing.assert_allclose(bites[0].entry, np.array([0.0, -1.0, 0.0]) * MM @ rot, atol=1e-12)
    np.testing.assert_allclose(bites[0].exit, np.array([0.0, 1.5, 0.0]) * MM @ rot, atol=1e-12)
    assert bites[0].depth == pytest.approx(1.0 * MM)


def test_stitch_metrics_against_the_declared_points() -> None:
    bites = find_bites(_thread(SITES), SURFACE, NORMAL)
    declared = {
        "entry_1": (-5.3 * MM, -4 * MM, 0.0),  # 0.3 mm off
        "exit_1": (-5 * MM, 4.4 * MM, 0.0),  # 0.4 mm off
        "entry_2": (0.0, -4 * MM, 0.0),
        "exit_2": (0.0, 4 * MM, 0.0),
        "entry_3": (5 * MM, -4 * MM, 0.0),  # 1 mm off (the bite is at x = 6 mm)
        "exit_3": (5 * MM, 4 * MM, 0.0),
        "anchor": (0.0, 0.0, 0.0),  # not an entry/exit pair: ignored
    }
    m = stitch_metrics(bites, declared)
    assert m["count"] == 3 and m["site"] == ["1", "2", "3"]
    assert m["entry_error_mm"] == pytest.approx([0.3, 0.0, 1.0], abs=1e-9)
    assert m["exit_error_mm"] == pytest.approx([0.4, 0.0, 1.0], abs=1e-9)
    assert m["bite_depth_mm"] == pytest.approx([2.0, 3.0, 2.5])
    # centres at x = -5, 0, 6 mm: spacings 5 and 6 mm
    assert m["spacing_mean_mm"] == pytest.approx(5.5)
    assert m["spacing_sd_mm"] == pytest.approx(math.sqrt(0.5), abs=1e-4)  # rounded to 0.1 um


def test_a_thread_that_went_in_at_the_exit_is_matched_both_ways() -> None:
    reverse = _bite(0.0, 2 * MM)[::-1]  # in at +y, out at -y
    pts = np.vstack([[[0.0, 6 * MM, 1 * MM]], reverse, [[0.0, -6 * MM, 1 * MM]]])
    m = stitch_metrics(
        find_bites(pts, SURFACE, NORMAL), {"entry": (0.0, -4 * MM, 0.0), "exit": (0.0, 4 * MM, 0.0)}
    )
    assert m["site"] == [""] and m["entry_error_mm"] == [0.0] and m["exit_error_mm"] == [0.0]
    assert m["spacing_mean_mm"] is None and m["spacing_sd_mm"] is None


def _parabola_bite(step: float, offset: float) -> tuple[np.ndarray, float]:
    """A bite z = -2 mm + y^2 / 4 mm sampled every ``step`` from ``offset``: the thread
    crosses the plane at y = -/+ sqrt(8) mm, between samples."""
    y = np.arange(-6 * MM + offset, 6 * MM, step)
    return np.c_[np.zeros_like(y), y, -2 * MM + y**2 / (4 * MM)], math.sqrt(8) * MM


def _sample_gap(pts: np.ndarray, y: float) -> float:
    """The distance between the two samples either side of y (the samples run along +y)."""
    k = int(np.searchsorted(pts[:, 1], y))
    return float(np.linalg.norm(pts[k] - pts[k - 1]))


def test_each_pierce_point_states_its_resolution_and_the_thread_crosses_within_it() -> None:
    # oracle: the parabola's own crossings; the spans, from the samples either side
    for step in (3.5 * MM, 1.0 * MM, 0.25 * MM):
        pts, y0 = _parabola_bite(step, 0.37 * MM)
        (bite,) = find_bites(pts, SURFACE, NORMAL)
        for pierce, span, y_true in (
            (bite.entry, bite.entry_span, -y0),
            (bite.exit, bite.exit_span, y0),
        ):
            assert span == pytest.approx(_sample_gap(pts, y_true), rel=1e-12)
            error = float(np.linalg.norm(np.asarray(pierce) - (0.0, y_true, 0.0)))
            assert 0.0 < error < span
        m = stitch_metrics([bite], {"entry": (0.0, -y0, 0.0), "exit": (0.0, y0, 0.0)})
        assert m["entry_error_mm"][0] < m["entry_resolution_mm"][0]
        assert m["entry_resolution_mm"] == [pytest.approx(1e3 * bite.entry_span, abs=1e-4)]
        assert m["exit_resolution_mm"] == [pytest.approx(1e3 * bite.exit_span, abs=1e-4)]
        assert m["spacing_resolution_mm"] is None
    # the coarse thread's points lie a capsule apart: 3.5 mm of resolution, not 0.25 mm
    assert (
        find_bites(_parabola_bite(3.5 * MM, 0.37 * MM)[0], SURFACE, NORMAL)[0].entry_span > 3.5 * MM
    )


def test_resolution_follows_the_pierce_point_when_the_bite_is_matched_the_other_way() -> None:
    # in at y = -1 mm over a 2.83 mm segment, out at y = 1.5 mm over a 4.47 mm one
    pts = np.array([[0.0, -2.0, 1.0], [0.0, 0.0, -1.0], [0.0, 1.0, -1.0], [0.0, 3.0, 3.0]]) * MM
    (bite,) = find_bites(pts, SURFACE, NORMAL)
    spans = [round(math.hypot(2.0, 2.0), 4), round(math.hypot(2.0, 4.0), 4)]
    straight = stitch_metrics([bite], {"entry": (0.0, -1 * MM, 0.0), "exit": (0.0, 1.5 * MM, 0.0)})
    swapped = stitch_metrics([bite], {"entry": (0.0, 1.5 * MM, 0.0), "exit": (0.0, -1 * MM, 0.0)})
    assert [straight["entry_resolution_mm"][0], straight["exit_resolution_mm"][0]] == spans
    assert [swapped["entry_resolution_mm"][0], swapped["exit_resolution_mm"][0]] == spans[::-1]
    assert straight["entry_error_mm"] == swapped["entry_error_mm"] == [0.0]
    # with no declared points the entry is the thread's first crossing
    alone = stitch_metrics([bite])
    assert alone["entry_resolution_mm"] == spans[:1] and alone["entry_error_mm"] == [None]


def test_the_spacings_resolution_sums_half_of_each_pierce_points_span() -> None:
    a, _ = _parabola_bite(3.5 * MM, 0.37 * MM)
    b, _ = _parabola_bite(1.0 * MM, 0.37 * MM)
    hop = np.array([[0.0, 6 * MM, 40 * MM], [5 * MM, -6 * MM, 40 * MM]])
    bites = find_bites(np.vstack([a, hop, b + np.array([5 * MM, 0.0, 0.0])]), SURFACE, NORMAL)
    assert len(bites) == 2
    m = stitch_metrics(bites)
    # half of each pierce point's sample gap, read from the two samplings themselves
    y0 = math.sqrt(8) * MM
    bound = sum(0.5 * (_sample_gap(pts, -y0) + _sample_gap(pts, y0)) for pts in (a, b))
    assert m["spacing_resolution_mm"] == pytest.approx(1e3 * bound, abs=1e-4)
    # oracle: the two parabolas' centres lie 5 mm apart; the sampled ones a little off it
    assert 0.0 < abs(m["spacing_mean_mm"] - 5.0) < m["spacing_resolution_mm"]


def test_one_knot_entry_per_stitch() -> None:
    from suture_engine.suture.knot import knot_lay

    pts = _thread(SITES)
    entries = knot_entries(pts, SURFACE, NORMAL, contact_diameter=0.5 * MM)
    assert [e["type"] for e in entries] == ["square", "unknot", "granny"]
    assert [e["stitch"] for e in entries] == [1, 2, 3]
    assert [(e["determinant"], e["v2"], e["v3"]) for e in entries[::2]] == [(9, 2, 0), (9, 2, 2)]
    assert all(e["seated"] is False for e in entries)  # the knots sit 2-3 mm above
    # the whole thread is the connected sum: what a single entry would (wrongly) say
    whole = knot_entries(pts, SURFACE, NORMAL, 0.5 * MM, bites=[])
    assert len(whole) == 1 and whole[0]["type"] not in ("square", "granny", "unknot")
    for e in entries[::2]:  # knot_lay's verdict on the stitch's own piece
        assert e["post_straight"] in (True, False, None) and e["lay"] in LAYS
    # an unknotted stitch has no lay: strands that merely touch are not two half hitches
    assert entries[1]["post_straight"] is None and "lay" not in entries[1]
    assert "no knot" in entries[1]["post_straight_reason"]
    first = pts[: int(np.argmax(pts[:, 2] > 100 * MM))]  # up to the first detour's top
    assert entries[0]["lay"] == knot_lay(first, diameter=0.5 * MM).lay


def test_a_passage_that_rises_near_the_surface_inside_the_tissue_is_one_bite() -> None:
    """One stitch whose thread, inside the channel, comes up to 0.03 mm under the surface
    (above the 0.05 mm that counts as inside, still below the plane): one bite, and one
    knot entry that holds the whole square knot. Seen in a run (algorithm 3's square knot,
    seed 2): counted as two bites with the same two crossings, the knot was cut between
    them and both halves read as unknots."""
    one = _thread(SITES[:1])
    assert len(find_bites(one, SURFACE, NORMAL)) == 1
    inside = np.flatnonzero(one[:, 2] < -0.05 * MM)
    middle = inside[len(inside) // 2]
    one[middle, 2] = -0.03 * MM
    runs = np.flatnonzero(np.diff(np.flatnonzero(one[:, 2] < -0.05 * MM)) > 1)
    assert len(runs) == 1  # two runs of points deeper than 0.05 mm, one passage
    bites = find_bites(one, SURFACE, NORMAL)
    assert len(bites) == 1
    np.testing.assert_allclose(bites[0].entry, (SITES[0][0], -4 * MM, 0.0), atol=1e-12)
    np.testing.assert_allclose(bites[0].exit, (SITES[0][0], 4 * MM, 0.0), atol=1e-12)
    assert bites[0].first == inside[0] and bites[0].last == inside[-1]
    entries = knot_entries(one, SURFACE, NORMAL, contact_diameter=0.5 * MM)
    assert len(entries) == 1 and entries[0]["type"] == "square"


def test_post_straight_is_null_with_a_reason_without_a_contact_diameter() -> None:
    one = _thread(SITES[:1])
    entries = knot_entries(one, SURFACE, NORMAL, contact_diameter=None)
    assert len(entries) == 1 and "stitch" not in entries[0]
    assert entries[0]["type"] == "square"
    assert entries[0]["post_straight"] is None and entries[0]["post_straight_reason"]


def test_tension_metrics_peak_and_final() -> None:
    m = tension_metrics([0.1, 2.5, math.nan, 1.0], [0.2, 3.0, 0.9])
    assert m == {
        "peak_tension_N": 2.5,
        "final_tension_N": 1.0,
        "peak_true_tension_N": 3.0,
        "final_true_tension_N": 0.9,
        "peak_true_tension_at": None,
    }
    assert tension_metrics([], None)["peak_true_tension_N"] is None
    at = {"t_s": 1.5, "state": "autonomous/tighten", "joint": 8}
    assert tension_metrics([1.0], [3.0], at)["peak_true_tension_at"] == at


def test_evaluate_trace_says_when_where_and_in_which_state_the_true_tension_peaked(
    tmp_path: Path,
) -> None:
    from suture_engine.trace import channels
    from suture_engine.trace.synthetic import synthetic_meta
    from suture_engine.trace.writer import TraceWriter

    path = tmp_path / "t.mcap"
    # a hand-written series: the peak (4.0 N at joint 16) in state "b", 2.5 ms in; a
    # message without a joint (an older trace) and a NaN on either side of it
    series = [(0, 1.0, 3), (1, 2.0, 5), (2, 4.0, 16), (3, math.nan, 9), (4, 4.0, 2), (5, 3.0, None)]
    with TraceWriter(path, synthetic_meta()) as w:
        w.write(channels.TRANSITIONS, 0, {"source": "", "dest": "a", "trigger": "start"})
        for k, value, joint in series:
            t_ns = 500_000 + k * 1_000_000
            if k == 2:
                w.write(channels.TRANSITIONS, t_ns, {"source": "a", "dest": "b", "trigger": "done"})
            msg: dict[str, object] = {"tension_N": value}
            if joint is not None:
                msg["joint"] = joint
            w.write(channels.GROUND_TRUTH_TENSION, t_ns, msg)
            w.write(channels.TENSION_ESTIMATED, t_ns, {"tension_N": 0.5, "robot": "r"})
    ev = evaluate_trace(path, SURFACE, NORMAL)
    assert ev.metrics["peak_true_tension_N"] == 4.0
    # the first tick at the peak (a later equal value does not move it), its state and joint
    assert ev.metrics["peak_true_tension_at"] == {"t_s": 0.0025, "state": "b", "joint": 16}
    assert ev.metrics["final_true_tension_N"] == 3.0


def test_evaluate_without_a_thread() -> None:
    ev = evaluate(None, [1.0, 0.5], None, SURFACE, NORMAL)
    assert ev.knot is None and ev.metrics["stitches"] is None
    assert ev.metrics["peak_tension_N"] == 1.0 and ev.metrics["final_tension_N"] == 0.5


def test_evaluate_trace_reads_the_last_centerline_and_the_tension_channels(tmp_path: Path) -> None:
    from suture_engine.trace import channels
    from suture_engine.trace.synthetic import synthetic_messages, synthetic_meta
    from suture_engine.trace.writer import TraceWriter

    path = tmp_path / "t.mcap"
    final = _thread(SITES)
    with TraceWriter(path, synthetic_meta()) as w:
        last_ns = 0
        for topic, t_ns, msg in synthetic_messages(0.3):
            w.write(topic, t_ns, msg)
            last_ns = t_ns
        # the recorder's centerline message, after the synthetic ones ({"x","y","z"})
        w.write(channels.GROUND_TRUTH_SUTURE, last_ns, {"centerline": final.tolist()})
    ev = evaluate_trace(path, SURFACE, NORMAL, contact_diameter=0.5 * MM)
    assert isinstance(ev.knot, list) and [k["type"] for k in ev.knot] == [
        "square",
        "unknot",
        "granny",
    ]
    assert ev.metrics["stitches"]["count"] == 3
    # the synthetic tension: 1 + 0.5 sin(2 pi 0.2 t) (+ up to 0.01 N noise on the estimate)
    t = np.arange(300) * 1e-3
    true = 1.0 + 0.5 * np.sin(2 * np.pi * 0.2 * t)
    assert ev.metrics["peak_true_tension_N"] == pytest.approx(true.max())
    assert ev.metrics["final_true_tension_N"] == pytest.approx(true[-1])
    assert true[-1] <= ev.metrics["final_tension_N"] <= true[-1] + 0.01
    # a synthetic trace's own centerlines ({"x","y","z"}, on the plane): no bite, one entry
    plain = tmp_path / "p.mcap"
    with TraceWriter(plain, synthetic_meta()) as w:
        for topic, t_ns, msg in synthetic_messages(0.1):
            w.write(topic, t_ns, msg)
    ev = evaluate_trace(plain, SURFACE, NORMAL)
    assert isinstance(ev.knot, dict) and ev.knot["type"] == "unknot"
    assert ev.metrics["stitches"]["count"] == 0


def test_with_the_wound_a_thread_hanging_below_the_plane_off_the_tissue_is_no_bite() -> None:
    thread = _thread(SITES)
    # the needle end hangs beyond the pad, below the surface plane, along the wound's
    # direction 40 mm away: under the plane, but across no wound
    dangle = np.array([[40, 0, 2], [42, 0, -8], [50, 0, -10], [58, 0, -8], [60, 0, 2]]) * MM
    pts = np.vstack([thread, dangle])
    assert len(find_bites(pts, SURFACE, NORMAL)) == 4
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    bites = find_bites(pts, SURFACE, NORMAL, wound=wound)
    assert [b.entry[0] for b in bites] == pytest.approx([s[0] for s in SITES])
    # a bite across the wound's line but beyond its end (+ 5 mm margin) does not count
    short = ((-15 * MM, 0.0, 0.0), (-8 * MM, 0.0, 0.0))
    assert len(find_bites(pts, SURFACE, NORMAL, wound=short)) == 1


def test_a_knot_whose_thread_left_the_tissue_is_flagged() -> None:
    one = _thread(SITES[:1])
    assert knot_entries(one, SURFACE, NORMAL, 0.5 * MM)[0]["through_tissue"] is True
    # the same knot with the thread lifted clear of the tissue: still a square knot, but
    # it binds no stitch
    lifted = one + np.array([0.0, 0.0, 10 * MM])
    entry = knot_entries(lifted, SURFACE, NORMAL, 0.5 * MM)[0]
    assert entry["type"] == "square" and entry["through_tissue"] is False
    entries = knot_entries(_thread(SITES), SURFACE, NORMAL, 0.5 * MM)
    assert [e["through_tissue"] for e in entries] == [True, True, True]


def test_a_taut_stitch_in_a_shallow_channel_is_a_bite_a_half_pulled_one_is_not() -> None:
    """A stitched start's channel is 0.5 mm deep; pulled taut, the thread in it runs 0.1-0.2
    mm under the surface (a thread resting on the pad lies a contact radius, 0.9 mm, above
    it). It still binds the stitch. A thread pulled back out of the exit hole, under the
    surface only on the entry side, binds none."""
    taut = np.vstack(
        [[[0.0, -20 * MM, 0.9 * MM]], _bite(0.0, 0.15 * MM, n=3), [[0.0, 20 * MM, 0.9 * MM]]]
    )
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    assert len(find_bites(taut, SURFACE, NORMAL, wound=wound)) == 1
    half = (
        np.array(
            [[0.6, -5.2, 0.3], [-0.1, -2.3, -0.12], [0.2, 0.7, 0.2], [0.5, -2.3, 0.6], [3, -8, 2]]
        )
        * MM
    )  # measured: algorithm 3, the thread turned back 3 mm short of the exit hole
    assert find_bites(half, SURFACE, NORMAL, wound=wound) == []


def test_an_interrupted_suture_is_one_entry_per_thread_in_order_along_the_wound() -> None:
    # three threads, one stitch each, loaded (and cut) in the halving order: middle first
    middle, left, right = (_thread([site]) for site in (SITES[1], SITES[0], SITES[2]))
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    ev = evaluate(right, [1.0], None, SURFACE, NORMAL, None, 0.5 * MM, wound, cut=[middle, left])
    assert isinstance(ev.knot, list)
    # along the wound: x = -5, 0, +6 mm
    assert [k["type"] for k in ev.knot] == ["square", "unknot", "granny"]
    assert [k["stitch"] for k in ev.knot] == [1, 2, 3]
    assert [k["thread"] for k in ev.knot] == [2, 1, 3]
    assert [k["cut"] for k in ev.knot] == [True, True, False]
    assert all(k["through_tissue"] for k in ev.knot)
    stitches = ev.metrics["stitches"]
    assert stitches["count"] == 3
    assert stitches["spacing_mean_mm"] == pytest.approx(5.5)  # 5 and 6 mm
    assert stitches["spacing_sd_mm"] == pytest.approx(np.std([5.0, 6.0], ddof=1), abs=1e-4)
    # one thread alone keeps the single-thread form (a dict, no numbering)
    alone = evaluate(left, [1.0], None, SURFACE, NORMAL, None, 0.5 * MM, wound)
    assert isinstance(alone.knot, dict) and "thread" not in alone.knot


def test_a_cut_thread_without_a_loaded_one_is_still_evaluated() -> None:
    ev = evaluate(None, [1.0], None, SURFACE, NORMAL, None, 0.5 * MM, cut=[_thread(SITES[:1])])
    assert isinstance(ev.knot, dict) and ev.knot["type"] == "square"
    assert ev.metrics["stitches"]["count"] == 1


def test_evaluate_trace_reads_the_cut_threads(tmp_path: Path) -> None:
    from suture_engine.trace import channels
    from suture_engine.trace.synthetic import synthetic_meta
    from suture_engine.trace.writer import TraceWriter

    path = tmp_path / "cut.mcap"
    first, second = _thread([SITES[0]]), _thread([SITES[2]])
    with TraceWriter(path, synthetic_meta()) as w:
        w.write(channels.GROUND_TRUTH_SUTURE, 0, {"centerline": first.tolist()})
        w.write(channels.GROUND_TRUTH_SUTURE_CUT, 1000, {"centerline": first.tolist()})
        w.write(channels.GROUND_TRUTH_SUTURE, 2000, {"centerline": second.tolist()})
    ev = evaluate_trace(path, SURFACE, NORMAL, contact_diameter=0.5 * MM)
    assert isinstance(ev.knot, list)
    assert [(k["type"], k["cut"]) for k in ev.knot] == [("square", True), ("granny", False)]
    # cut and nothing loaded after: the cut thread alone, not counted twice
    only = tmp_path / "only.mcap"
    with TraceWriter(only, synthetic_meta()) as w:
        w.write(channels.GROUND_TRUTH_SUTURE, 0, {"centerline": first.tolist()})
        w.write(channels.GROUND_TRUTH_SUTURE_CUT, 1000, {"centerline": first.tolist()})
    ev = evaluate_trace(only, SURFACE, NORMAL, contact_diameter=0.5 * MM)
    assert isinstance(ev.knot, dict) and ev.knot["type"] == "square"


def test_a_thread_sagging_into_the_wounds_opening_is_no_bite() -> None:
    """A simulated thread resting across the pad's 1 mm slit sags into it. Measured on a
    registered run of algorithm 3 (a square knot, its lift of the held end on): after the
    knot one centerline point lay 0.09 mm under the plane over the wound line, its plane
    crossings 0.06 and 0.04 mm either side of it. Counted as a second bite it cut the
    square into two unknotted pieces. Lying in the wound is not a stitch: with the wound
    given, the thread is one bite and its square knot is classified whole. A shallow bite
    whose pierce points lie beside the opening still counts."""
    one = _thread(SITES[:1])
    x = one[-1][0]  # the thread goes on from its end, 10 mm past the stitch, over the wound
    sag = np.array([[x, -0.6 * MM, 0.5 * MM], [x, 0.0, -0.09 * MM], [x, 0.6 * MM, 0.5 * MM],
                    [x, 6 * MM, 2 * MM]])  # fmt: skip
    pts = np.vstack([one, sag])
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    assert len(find_bites(pts, SURFACE, NORMAL)) == 2  # under the plane, twice
    bites = find_bites(pts, SURFACE, NORMAL, wound=wound)
    assert len(bites) == 1 and bites[0].entry[0] == pytest.approx(SITES[0][0])
    entries = knot_entries(pts, SURFACE, NORMAL, 0.5 * MM, bites)
    assert [e["type"] for e in entries] == ["square"]
    assert len(find_bites(pts, SURFACE, NORMAL, wound=wound, in_wound=0.0, opening=0.0)) == 2
    # a shallow bite whose pierce points lie 1.5 mm either side of the line is a stitch
    shallow = np.vstack([[[0.0, -20 * MM, 0.9 * MM]], _bite(0.0, 0.1 * MM, 1.5 * MM, n=5),
                         [[0.0, 20 * MM, 0.9 * MM]]])  # fmt: skip
    assert len(find_bites(shallow, SURFACE, NORMAL, wound=wound)) == 1


@pytest.mark.parametrize(
    "passage",
    [
        # a square drawn down into the slit (friction draw 36 of algorithm 3's square knot
        # with the held end kept up): in 3.32 mm out, 2.66 mm deep, out 0.34 mm past the line
        [
            [0.0, 6.0, 2.0],
            [0.0, 3.37, 0.047],
            [0.04, 0.82, -2.34],
            [3.2, -0.45, -2.66],
            [3.3, -0.5, 1.5],
        ],
        # a tail sagging in from 2.59 mm out to 0.17 mm past the line (a single throw of a
        # calibration sweep), and the mirror of it
        [[0.0, -6.0, 1.0], [0.0, -2.0, -0.11], [0.0, 0.5, 0.02], [0.0, 4.0, 1.0]],
        [[2.0, 6.0, 1.0], [2.0, 2.0, -0.11], [2.0, -0.5, 0.02], [2.0, -4.0, 1.0]],
    ],
)
def test_a_thread_going_into_the_wounds_opening_from_one_side_is_no_bite(
    passage: list[list[float]],
) -> None:
    """The thread can pass under the plane through the wound's opening with only one of its
    crossings beside the line: a knot drawn down into the slit, or a tail that sags in from
    one side. Counted as a bite, each cut the thread's knot into unknotted pieces (two runs
    ended with a square and a trefoil evaluated as unknots). A passage that meets the plane
    within ``IN_OPENING`` of the line on either side is not a bite."""
    one = _thread(SITES[:1])
    x = one[-1][0]
    pts = np.vstack([one, np.array(passage) * MM + [x, 0.0, 0.0]])
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    assert len(find_bites(pts, SURFACE, NORMAL, wound=wound, opening=0.0)) == 2
    bites = find_bites(pts, SURFACE, NORMAL, wound=wound)
    assert len(bites) == 1 and bites[0].entry[0] == pytest.approx(SITES[0][0])
    entries = knot_entries(pts, SURFACE, NORMAL, 0.5 * MM, bites)
    assert [e["type"] for e in entries] == ["square"]


def test_a_bite_whose_interpolated_pierce_point_lies_near_the_wound_is_still_a_bite() -> None:
    """The PyBullet thread's centerline has one point per 3.5 mm capsule, so a bite's
    interpolated pierce point can lie much nearer the wound line than where the thread
    goes in: a stored run's stitch, declared 4 mm out, crossed the plane 0.84 mm and
    2.43 mm either side of it. It is a bite."""
    pts = np.array([[0.0, -6.0, 1.0], [0.0, -1.6, 0.3], [0.0, -0.26, -0.23], [0.0, 4.77, 0.2],
                    [0.0, 8.0, 2.0]]) * MM  # fmt: skip
    wound = ((-15 * MM, 0.0, 0.0), (15 * MM, 0.0, 0.0))
    bites = find_bites(pts, SURFACE, NORMAL, wound=wound)
    assert len(bites) == 1
    assert bites[0].entry[1] == pytest.approx(-0.84 * MM, abs=0.01 * MM)
    assert bites[0].exit[1] == pytest.approx(2.43 * MM, abs=0.02 * MM)
    assert not find_bites(pts, SURFACE, NORMAL, wound=wound, opening=1e-3)
