"""The scene model: Tables 7.1 and 7.2, the derived tension limit, and its checks."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from suture_engine.language.scene import (
    GRAVITY,
    GRIP_FRACTION,
    KNOT_PULL_STRENGTH_KG,
    SUTURE_DIAMETER_MM,
    TISSUE_PULLOUT_N,
    Scene,
)


def _scene(**changes: object) -> dict[str, object]:
    data: dict[str, object] = {
        "robots": {"endobot_1": {"tool": "stitcher"}, "endobot_2": {"tool": "hook-grasper"}},
        "tissue": {"type": "skin", "wound": {"start": [0, 0, 0], "end": ["1 cm", 0, 0]}},
        "suture": {"usp": "2-0", "length": "30 cm"},
    }
    data.update(changes)
    return data


def test_tables_as_printed_in_the_thesis() -> None:
    assert KNOT_PULL_STRENGTH_KG == {
        "0": 2.16,
        "2-0": 1.44,
        "3-0": 0.96,
        "4-0": 0.60,
        "5-0": 0.40,
        "6-0": 0.20,
    }
    assert SUTURE_DIAMETER_MM["3-0"] == (0.20, 0.249)
    assert TISSUE_PULLOUT_N == {"fat": 1.96, "muscle": 12.45, "skin": 17.85, "fascia": 36.98}


@pytest.mark.parametrize(
    ("usp", "tissue", "factor", "expected"),
    [
        ("2-0", "skin", 0.5, 0.5 * 1.44 * 9.80665),  # the suture is weaker (14.1 N < 17.85 N)
        ("0", "fat", 1.0, 1.96),  # the tissue is weaker
        ("6-0", "fascia", 0.8, 0.8 * 0.20 * 9.80665),
    ],
)
def test_tension_limit_is_the_weaker_times_the_safety_factor(
    usp: str, tissue: str, factor: float, expected: float
) -> None:
    data = _scene(
        suture={"usp": usp, "length": "30 cm"},
        tissue={"type": tissue, "wound": {"start": [0, 0, 0], "end": [0.01, 0, 0]}},
        safety_factor=factor,
    )
    scene = Scene.model_validate(data)
    assert scene.tension_limit == pytest.approx(expected)
    assert scene.suture.knot_pull_strength == pytest.approx(KNOT_PULL_STRENGTH_KG[usp] * GRAVITY)


def test_usp_zero_written_as_a_number() -> None:
    assert Scene.model_validate(_scene(suture={"usp": 0, "length": 0.3})).suture.usp == "0"


@pytest.mark.parametrize(
    "changes",
    [
        {"robots": {"endobot_1": {"tool": "stitcher"}}},
        {"robots": {"a": {"tool": "laser"}, "b": {"tool": "grasper"}}},
        {"suture": {"usp": "9-0", "length": 0.3}},
        {"suture": {"usp": "2-0", "length": "30 deg"}},
        {"tissue": {"type": "bone", "wound": {"start": [0, 0, 0], "end": [1, 0, 0]}}},
        {"safety_factor": 1.5},
        {"robots": {"a": {"tool": "stitcher", "joint_limits": {"yaw": ["10 deg", "-10 deg"]}},
                    "b": {"tool": "grasper"}}},
        {"colour": "blue"},
        # grip force: graspers only, positive, at most the tension limit (7.06 N here)
        {"robots": {"a": {"tool": "stitcher", "grip_force": "3 N"}, "b": {"tool": "grasper"}}},
        {"robots": {"a": {"tool": "stitcher"}, "b": {"tool": "grasper", "grip_force": 0}}},
        {"robots": {"a": {"tool": "stitcher"}, "b": {"tool": "grasper", "grip_force": "8 N"}}},
        {"robots": {"a": {"tool": "stitcher"}, "b": {"tool": "grasper", "grip_force": "3 mm"}}},
        # the wound's opening: a length, not negative
        {"tissue": {"type": "skin", "wound": {"start": [0, 0, 0], "end": [0.01, 0, 0],
                                              "gap": "-1 mm"}}},
        {"tissue": {"type": "skin", "wound": {"start": [0, 0, 0], "end": [0.01, 0, 0],
                                              "gap": "1 N"}}},
        # the thread's contacts: a positive stiffness, a damping not negative
        {"suture": {"usp": "2-0", "length": 0.3, "contact_stiffness": 0}},
        {"suture": {"usp": "2-0", "length": 0.3, "contact_stiffness": "10 N"}},
        {"suture": {"usp": "2-0", "length": 0.3, "contact_stiffness": "10 kN/m",
                    "contact_damping": "-1 N*s/m"}},
        # the joints' shape: a YAML boolean, not a number or a word
        {"suture": {"usp": "2-0", "length": 0.3, "smooth_joints": 1}},
        {"suture": {"usp": "2-0", "length": 0.3, "smooth_joints": "yes"}},
        # the thread's damping: a rate, not negative
        {"suture": {"usp": "2-0", "length": 0.3, "damping": "-1 1/s"}},
        {"suture": {"usp": "2-0", "length": 0.3, "damping": "5 N*s/m"}},
        # the weight it keeps: a positive mass per length
        {"suture": {"usp": "2-0", "length": 0.3, "weight": 0}},
        {"suture": {"usp": "2-0", "length": 0.3, "weight": "4 g"}},
    ],
)  # fmt: skip
def test_bad_scenes_are_rejected(changes: dict[str, object]) -> None:
    with pytest.raises(ValidationError):
        Scene.model_validate(_scene(**changes))


def test_grip_force_defaults_to_a_fraction_of_the_tension_limit() -> None:
    scene = Scene.model_validate(_scene())
    assert scene.tension_limit == pytest.approx(0.5 * 1.44 * GRAVITY)
    assert scene.grip_force("endobot_2") == pytest.approx(GRIP_FRACTION * scene.tension_limit)
    assert GRIP_FRACTION == 0.9
    robots = {
        "endobot_1": {"tool": "stitcher"},
        "endobot_2": {"tool": "grasper", "grip_force": "5 N"},
    }
    assert Scene.model_validate(_scene(robots=robots)).grip_force("endobot_2") == 5.0


@pytest.mark.parametrize(("gap", "expected"), [(None, None), ("0 mm", 0.0), ("1.5 mm", 1.5e-3)])
def test_the_wounds_opening_is_a_length_or_left_to_the_simulator(
    gap: str | None, expected: float | None
) -> None:
    wound: dict[str, object] = {"start": [0, 0, 0], "end": ["1 cm", 0, 0]}
    if gap is not None:
        wound["gap"] = gap
    scene = Scene.model_validate(_scene(tissue={"type": "skin", "wound": wound}))
    assert scene.tissue.wound.gap == (None if expected is None else pytest.approx(expected))


def test_the_threads_contacts_are_springs_in_units_or_left_rigid() -> None:
    rigid = Scene.model_validate(_scene()).suture
    assert (rigid.contact_stiffness, rigid.contact_damping) == (None, 5.0)
    suture = {"usp": "2-0", "length": 0.3, "contact_stiffness": "10 kN/m",
              "contact_damping": "2 N*s/m"}  # fmt: skip
    soft = Scene.model_validate(_scene(suture=suture)).suture
    assert soft.contact_stiffness == pytest.approx(1e4)
    assert soft.contact_damping == pytest.approx(2.0)


def test_the_threads_joints_are_grooves_unless_declared_smooth() -> None:
    assert Scene.model_validate(_scene()).suture.smooth_joints is False
    suture = {"usp": "2-0", "length": 0.3, "smooth_joints": True}
    assert Scene.model_validate(_scene(suture=suture)).suture.smooth_joints is True


def test_the_threads_damping_is_a_rate_or_left_to_the_simulator() -> None:
    assert Scene.model_validate(_scene()).suture.damping is None
    for given, rate in (("20 1/s", 20.0), ("20 Hz", 20.0), (5, 5.0)):
        suture = {"usp": "2-0", "length": 0.3, "damping": given}
        assert Scene.model_validate(_scene(suture=suture)).suture.damping == pytest.approx(rate)


def test_the_threads_weight_is_a_mass_per_length_or_left_to_the_simulator() -> None:
    assert Scene.model_validate(_scene()).suture.weight is None
    suture = {"usp": "2-0", "length": 0.3, "weight": "4 g/m"}
    assert Scene.model_validate(_scene(suture=suture)).suture.weight == pytest.approx(4e-3)
