"""One contract over every registered skill, with parameters taken from the bundled procedures.

Each skill is built from a ``with`` found in ``procedures/`` (or from its Params'
defaults), prints its parameters in ``repr``, returns a list from ``check``, and
on a synthetic observation ``start`` + ``step`` return a command (a
:class:`StepResult` or a :class:`Command`) or raise only the typed
:class:`SkillNotAvailable`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skills.base import SkillNotAvailable
from skills.registry import available_skills, get_skill
from suture_engine.language.loader import load_procedure
from suture_engine.runtime.context import SkillContext
from suture_engine.runtime.observation import (
    Command,
    Observation,
    RobotObservation,
    SceneGeometry,
    StepResult,
    ToolState,
)
from suture_engine.runtime.testing import DEFAULT_Q

ROOT = Path(__file__).resolve().parent.parent


def _states(proc: Any, on: bool = True) -> list[tuple[Any, Any, bool]]:
    """Every skill state with whether it can run (``when:`` may turn it, or the
    sub-procedure it is in, off)."""
    out = []
    for state in proc.states.values():
        if state.skill is not None and state.params is not None:
            out.append((proc, state, on and state.enabled))
        if state.use is not None:
            out.extend(_states(state.use, on and state.enabled))
    return out


def _samples() -> dict[str, tuple[Any, Any]]:
    found: dict[str, tuple[Any, Any]] = {}
    off: dict[str, tuple[Any, Any]] = {}
    for path in sorted((ROOT / "procedures").glob("*.yaml")):
        for proc, state, can_run in _states(load_procedure(path)):
            # a state `when:` turns off may refer to what only another scene declares
            (found if can_run else off).setdefault(state.skill, (proc, state.params))
    return {**off, **found}


SAMPLES = _samples()
FALLBACK: dict[str, dict[str, Any]] = {
    "release": {"robot": "grasper"},
    "hold": {"robot": "stitcher"},
    "wait-for-operator": {},
}
"""Skills no bundled procedure uses yet, with a minimal ``with``."""


@pytest.fixture(scope="module")
def default_proc() -> Any:
    return load_procedure(ROOT / "procedures" / "knot-algorithm-1.yaml")


def _ctx(proc: Any) -> tuple[SkillContext, Observation]:
    scene = proc.scene
    robots = {}
    poses = {}
    for name, spec in scene.robots.items():
        tool = ToolState(spec.tool, jaw_closed=True)
        robots[name] = RobotObservation(np.array(DEFAULT_Q), np.zeros(4), np.zeros(6), tool)
        rot = Rotation.from_euler("xyz", spec.base.rpy).as_matrix()
        poses[name] = (tuple(spec.base.position), tuple(rot.reshape(-1)))
    points = scene.tissue.points
    geometry = SceneGeometry(
        points.get("entry_2", (0.0, -0.004, 0.0)),
        points.get("exit_2", (0.0, 0.004, 0.0)),
        scene.tissue.normal,
        {n: tuple(s.base.position) for n, s in scene.robots.items()},
    )
    obs = Observation(0, 0.0, robots, geometry)
    ctx = SkillContext("contract", dict(proc.roles), 1e-3, obs, scene, dict(proc.params), poses)
    return ctx, obs


def _build(name: str, default_proc: Any) -> tuple[Any, Any]:
    cls = get_skill(name)
    if name in SAMPLES:
        proc, params = SAMPLES[name]
        return cls(params), proc
    return cls(cls.Params.model_validate(FALLBACK.get(name, {}))), default_proc


def test_every_skill_has_sample_parameters() -> None:
    # the bundled skills only: other tests register example plugins (e.g. the plugin
    # page's ``nudge``) in the same session
    bundled = {n for n in available_skills() if get_skill(n).__module__.startswith("skills.")}
    missing = bundled - set(SAMPLES) - set(FALLBACK)
    assert not missing, f"no sample parameters for {sorted(missing)}"


@pytest.mark.parametrize("name", available_skills())
def test_skill_contract(name: str, default_proc: Any) -> None:
    skill, proc = _build(name, default_proc)
    text = repr(skill)
    assert text.startswith(type(skill).__name__ + "(")
    for field in type(skill.params).model_fields:
        assert f"{field}=" in text
    problems = type(skill).check(skill.params, proc.scene)
    assert isinstance(problems, list)
    ctx, obs = _ctx(proc)
    try:
        skill.start(ctx)
        result = skill.step(ctx, obs)
    except SkillNotAvailable as exc:
        assert exc.code == "skill-not-available" and exc.skill == name
        return
    assert isinstance(result, (StepResult, Command))
    command = result.command if isinstance(result, StepResult) else result
    assert set(command.robots) <= set(proc.scene.robots)
    for rc in command.robots.values():
        for arr in (rc.q, rc.qd, rc.tau):
            assert arr is None or (arr.shape == (4,) and np.all(np.isfinite(arr)))
