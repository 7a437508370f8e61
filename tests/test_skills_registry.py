"""The skill catalogue: every skill registered, contract checks, suggestions, entry points."""

from __future__ import annotations

import inspect

import pytest
from pydantic import ValidationError

import skills.registry as registry
from skills.base import Skill, SkillNotAvailable, SkillParams
from skills.registry import BUILTIN_SKILLS, UnknownSkill, available_skills, get_skill

REQUIRED = {
    "move-constrained",
    "pass-needle",
    "place-knot",
    "tension-regulate",
    "grasp",
    "release",
    "hook",
    "pass-jaws",
    "rotate-about",
    "wrap",
    "hold",
    "move-to",
    "wait-for-operator",
}


# skills whose running arrives with later work: step must say so with a typed error
def test_every_required_skill_is_registered() -> None:
    assert set(available_skills()) >= REQUIRED


@pytest.mark.parametrize("name", sorted(BUILTIN_SKILLS))
def test_skill_contract(name: str) -> None:
    cls = get_skill(name)
    assert issubclass(cls, Skill) and cls.name == name
    assert issubclass(cls.Params, SkillParams)
    assert cls.Params.model_config.get("extra") == "forbid"
    assert inspect.getdoc(cls) and inspect.getdoc(cls.Params)
    for field, info in cls.Params.model_fields.items():  # every parameter is documented
        assert info.description or _attribute_doc(cls.Params, field), f"{name}.{field}"
    with pytest.raises(ValidationError) as info:
        cls.Params.model_validate({"no_such_parameter": 1})
    assert any(e["type"] == "extra_forbidden" for e in info.value.errors())


def _attribute_doc(model: type, field: str) -> bool:
    source = inspect.getsource(model)
    lines = source.splitlines()
    for i, line in enumerate(lines):
        if line.strip().startswith(f"{field}:"):
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            return j < len(lines) and lines[j].strip().startswith('"""')
    return False


def _minimal(name: str) -> dict[str, object]:
    cls = get_skill(name)
    values: dict[str, object] = {}
    samples: dict[str, object] = {
        "robot": "stitcher",
        "around": "grasper",
        "post": "grasper",
        "loop": "stitcher",
        "entry": "entry_1",
        "exit": "exit_1",
        "site": "knot_1",
        "pull_length": 0.02,
        "tension": 2.0,
        "angle": 1.0,
        "action": "extend",
        "fixture": "line",
        "target": "entry_1",
    }
    for field, info in cls.Params.model_fields.items():
        if info.is_required():
            values[field] = samples[field]
    return values


def test_skill_not_available_names_the_skill_and_what_is_missing() -> None:
    error = SkillNotAvailable("tension-regulate", "no scene geometry")
    assert error.code == "skill-not-available"
    assert error.skill == "tension-regulate"
    assert "tension-regulate" in error.message and "no scene geometry" in error.message


def test_repr_prints_the_parameters() -> None:
    cls = get_skill("wrap")
    text = repr(cls(cls.Params.model_validate({"robot": "stitcher", "around": "grasper"})))
    assert "robot='stitcher'" in text and "around='grasper'" in text and "turns=1" in text


def test_unknown_skill_suggests_the_closest_names() -> None:
    with pytest.raises(UnknownSkill) as info:
        get_skill("move-constraind")
    err = info.value
    assert err.code == "unknown-skill"
    assert err.suggestions[0] == "move-constrained"
    assert "did you mean 'move-constrained'" in err.message
    assert set(err.available) >= REQUIRED


def test_third_party_skills_come_from_the_entry_point_group(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    class FakeEntryPoint:
        name = "suture-twice"
        value = "skills.hold:Hold"
        group = registry.ENTRY_POINT_GROUP

    seen: list[str] = []

    def fake_entry_points(group: str) -> list[FakeEntryPoint]:
        seen.append(group)
        return [FakeEntryPoint()]

    monkeypatch.setattr(registry, "_entry_points", None)
    monkeypatch.setattr("importlib.metadata.entry_points", fake_entry_points)
    assert "suture-twice" in available_skills()
    assert seen == ["suture_engine.skills"]
    monkeypatch.setattr(registry, "_registered", dict(registry._registered))
    assert get_skill("suture-twice").name == "hold"


def test_register_skill_at_run_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(registry, "_registered", {})

    class NoopParams(SkillParams):
        """No parameters."""

    @registry.register_skill
    class Noop(Skill):
        """Does nothing."""

        name = "noop"
        Params = NoopParams

        def step(self, ctx: object, obs: object) -> None:
            return None

    assert get_skill("noop") is Noop
    assert "noop" in available_skills()
