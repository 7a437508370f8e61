"""``benchmarks/knot_hold.py``: laid knots drawn tight with rigid or spring contacts."""

from __future__ import annotations

import pytest
from benchmark_modules import load_benchmark

kh = load_benchmark("knot_hold")


def test_a_rigid_overhand_drawn_to_3n_reads_a_tension_no_tool_applies() -> None:
    """The artefact behind the over-limit true tensions: drawn to 3 N, a capsule wedged
    0.7 mm into another is pushed out by the rigid contact against its own joint, which
    reads several times the pull. With spring contacts the same knot reads far less. Both
    keep the trefoil and hold the pull."""
    rigid = kh.hold("overhand", 60, 0.0, 3.0, 2.0)
    soft = kh.hold("overhand", 60, 1e4, 3.0, 2.0)
    for held in (rigid, soft):
        assert held.type.startswith("trefoil"), held
        assert held.min_hold > 2.4, held
    assert rigid.peak > 3 * 3.0, rigid
    assert soft.peak < rigid.peak / 2, (soft, rigid)
    assert soft.deepest > rigid.deepest


def test_smooth_joints_hold_the_overhand_at_3n_without_the_wedge() -> None:
    """With no groove at the joints for a crossing capsule to wedge open, the overhand
    drawn to 3 N reads at most half again the pull inside the knot (the tip-to-tip chain:
    over three times it) (``python benchmarks/knot_hold.py --target 3 --joints
    tip,smooth --stiffness 0``)."""
    overhand = kh.hold("overhand", 60, 0.0, 3.0, 2.0, joints="smooth")
    assert overhand.type.startswith("trefoil"), overhand
    assert overhand.min_hold > 2.4, overhand
    assert overhand.peak < 1.5 * 3.0, overhand


@pytest.mark.slow
def test_smooth_joints_keep_the_laid_square_at_3n_where_the_tip_to_tip_chain_loses_it() -> None:
    """The laid square drawn to 3 N keeps both throws on smooth joints, where the
    tip-to-tip chain loses one (about 15 s)."""
    square = kh.hold("square", 80, 0.0, 3.0, 2.0, joints="smooth")
    assert square.type == "square", square
    assert square.min_hold > 1.0, square
    assert kh.hold("square", 80, 0.0, 3.0, 2.0).type != "square"


@pytest.mark.parametrize(
    "bad", [["--stiffness", "-1"], ["--stiffness", "ten"], ["--joints", "round"]]
)
def test_command_line_refuses_a_stiffness_it_cannot_use(bad: list[str]) -> None:
    with pytest.raises(SystemExit) as err:
        kh.main(bad)
    assert err.value.code == 2
