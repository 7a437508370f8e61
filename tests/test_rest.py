"""The thread's rest test (:mod:`backends.pybullet.rest`): a knot pulled taut and let go."""

from __future__ import annotations

import pytest

from backends.pybullet.rest import released_knot_travel
from backends.pybullet.suture import SutureParams

WEIGHTS = pytest.mark.parametrize("weight", [1e-4, 4e-3], ids=["real-weight", "4g-per-m"])


@WEIGHTS
@pytest.mark.parametrize(
    ("throws", "tied"),
    [((False,), "trefoil"), ((False, True), "square")],
    ids=["overhand", "square"],
)
def test_a_knot_pulled_taut_and_let_go_stays_put_when_the_thread_is_damped(
    throws: tuple[bool, ...], tied: str, weight: float
) -> None:
    """At a damping rate of 20 /s the released knot's thread moves at most 5 mm in 2 s
    (measured with the real thread's weight: 3.1 mm overhand, 3.6 mm square; keeping
    4 g/m of weight: 2.4 and 2.5 mm) and stays tied."""
    knot = released_knot_travel(throws, 20.0, params=SutureParams(real_mass_per_length=weight))
    assert knot.reached
    assert knot.travel < 5e-3
    assert knot.type.startswith(tied)


@WEIGHTS
def test_a_straight_thread_pulled_taut_and_let_go_springs_back_by_its_stretch_alone(
    weight: float,
) -> None:
    """The same pull on a straight thread: it springs back by its chain's stretch, 0.75 mm
    measured, and lies still; the bound the knots' 5 mm is set a few times above."""
    straight = released_knot_travel(None, 20.0, params=SutureParams(real_mass_per_length=weight))
    assert straight.reached
    assert straight.travel < 1.5e-3
    assert straight.type == "unknot"


@pytest.mark.xfail(
    strict=True,
    reason="at the default damping (0.5 /s) the mass-scaled thread coasts on the energy "
    "its stretch gives back: a released knot flings its ends about 0.13 m (issue 6)",
)
def test_a_knot_pulled_taut_and_let_go_stays_put_at_the_default_damping() -> None:
    """The same rest test at the thread's default damping, which fails it."""
    knot = released_knot_travel((False,), SutureParams().linear_damping)
    assert knot.reached
    assert knot.travel < 5e-3
