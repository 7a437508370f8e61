"""benchmarks/failure_analysis.py: the thesis' knot failures in physics, detected from ground truth.

Fast: the hand-built lays are what they claim, and a strand wound round a post laid in
the simulator and pulled straight by its end is judged two half hitches. Slow: the
square lay under the same pull stays square; the jig's second throw without the mirror
is a granny, with it a square knot.
"""

from __future__ import annotations

import pytest
from benchmark_modules import load_benchmark

from suture_engine.suture.knot import knot_lay
from suture_engine.suture.topology import classify_knot

fa = load_benchmark("failure_analysis")


def test_the_hand_built_lays_are_what_they_claim() -> None:
    square = fa.square_lay()
    assert classify_knot(square).type == "square"
    assert knot_lay(square, diameter=1.0).lay == "square"
    hitches = knot_lay(fa.half_hitches_lay(), diameter=1.0)
    assert hitches.lay == "half-hitches" and hitches.straight_strand == 1


def test_a_wound_strand_pulled_straight_by_its_post_is_two_half_hitches() -> None:
    pytest.importorskip("pybullet")
    r = fa.lay_and_pull("half-hitches", settle=0.2, pull=0.5)
    assert r.pull.reached
    lay = r.lay_pulled
    assert lay.lay == "half-hitches", lay
    assert lay.post_straight is False
    assert lay.straight_strand == 1  # the strand whose end was pulled
    assert lay.straightness[0] > 0.95 and lay.straightness[1] < 0.5
    assert r.stretch < 0.05


@pytest.mark.slow
def test_the_square_lay_under_the_same_pull_stays_square() -> None:
    r = fa.lay_and_pull("square", settle=0.2, pull=0.5)
    assert r.pull.reached
    assert r.lay_pulled.lay == "square", r.lay_pulled
    assert r.lay_pulled.post_straight is True
    assert r.type_pulled == "square"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("mirrored", "expected", "v3"), [(True, "square", 0), (False, "granny", 2)]
)
def test_leaving_out_the_mirror_ties_a_granny(mirrored: bool, expected: str, v3: int) -> None:
    j = fa.tie_two_throws(mirrored)
    assert j.type == expected, j
    assert j.determinant == 9 and j.v2 == 2 and abs(j.v3) == v3, j
    assert j.reached
