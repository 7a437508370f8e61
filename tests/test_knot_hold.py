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


@pytest.mark.parametrize("bad", [["--stiffness", "-1"], ["--stiffness", "ten"]])
def test_command_line_refuses_a_stiffness_it_cannot_use(bad: list[str]) -> None:
    with pytest.raises(SystemExit) as err:
        kh.main(bad)
    assert err.value.code == 2
