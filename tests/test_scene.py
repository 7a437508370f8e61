"""Scene assembly: from the scene model (robots, mounted tools, tissue, suture) and from dicts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from backends.pybullet.scene import SceneError, build_scene
from backends.pybullet.tools import BentTipGrasper, Grasper, Stitcher
from suture_engine.language.scene import Scene as SceneModel

ROOT = Path(__file__).resolve().parent.parent


def _model(name: str) -> SceneModel:
    return SceneModel.model_validate(
        yaml.safe_load((ROOT / "procedures/scenes" / name).read_text())
    )


def test_model_scene_robots_at_base_poses_with_tools_on_their_tool_links() -> None:
    import pybullet as p

    model = _model("bench.yaml")
    scene = build_scene(model, seed=3)
    try:
        assert sorted(scene.robots) == sorted(model.robots)
        for name, spec in model.robots.items():
            robot = scene.robots[name]
            base, _ = p.getBasePositionAndOrientation(robot.body_id, physicsClientId=scene.client)
            assert np.allclose(base, spec.base.position, atol=1e-9)
        assert isinstance(scene.tools["endobot_1"], Stitcher)
        hook = scene.tools["endobot_2"]
        assert isinstance(hook, Grasper) and hook.hook_body >= 0
        assert scene.suture.params.length == pytest.approx(model.suture.length)
        assert scene.suture.params.n_segments >= 40
        # The stitch runs between the first named bite's entry and exit points.
        assert scene.tissue is not None
        assert np.allclose(scene.tissue.entry, model.tissue.points["entry_1"])
        assert np.allclose(scene.tissue.exit, model.tissue.points["exit_1"])
        for _ in range(500):
            scene.step()
        # Robots hold their start joints; each tool tip sits on its robot's tool link.
        for name, robot in scene.robots.items():
            assert np.allclose(robot.true_state().q, scene.hold[name], atol=5e-3)
            link, _ = robot.true_tool_pose()
            tip, _ = scene.tools[name].pose()
            assert np.linalg.norm(np.asarray(tip) - link) < 1e-3
        # Moving a robot moves its tool.
        before = np.asarray(scene.tools["endobot_2"].pose()[0])
        q = scene.hold["endobot_2"]
        scene.hold["endobot_2"] = (q[0], q[1], q[2], q[3] + 0.02)
        for _ in range(1000):
            scene.step()
        after = np.asarray(scene.tools["endobot_2"].pose()[0])
        link, _ = scene.robots["endobot_2"].true_tool_pose()
        assert np.linalg.norm(after - link) < 1e-3
        assert np.linalg.norm(after - before) > 0.015
        # The needle is locked in the stitcher's jaw.
        stitcher = scene.tools["endobot_1"]
        assert isinstance(stitcher, Stitcher)
        jaw, _ = p.getBasePositionAndOrientation(stitcher.jaws[0], physicsClientId=scene.client)
        needle, _ = p.getBasePositionAndOrientation(
            scene.suture.needle_body, physicsClientId=scene.client
        )
        assert np.linalg.norm(np.asarray(jaw) - needle) < 1e-3
    finally:
        scene.close()


def test_model_scene_without_stitcher_starts_stitched_through_the_tissue() -> None:
    model = _model("bench-bent-tip.yaml")
    scene = build_scene(model)
    try:
        kinds = {type(t) for t in scene.tools.values()}
        assert BentTipGrasper in kinds or Stitcher in kinds
        if not any(isinstance(t, Stitcher) for t in scene.tools.values()):
            assert scene.tissue is not None and scene.tissue.suture is scene.suture
            for _ in range(200):
                scene.step()
            # A 7.5 mm capsule in an 8 mm bite: at least one lies in the channel, below the
            # surface, and the thread stays threaded.
            assert len(scene.tissue.inside) >= 1
            assert scene.suture.centerline()[:, 2].min() < -1e-3
    finally:
        scene.close()


def test_same_seed_same_run() -> None:
    def run() -> np.ndarray:
        scene = build_scene({"suture": {"knot": "overhand", "segments": 60}}, seed=7)
        try:
            left, right = scene.tools["left"], scene.tools["right"]
            assert isinstance(left, Grasper) and isinstance(right, Grasper)
            left.close()
            right.close()
            for k in range(400):
                x = right.pose()[0]
                if k > 120:
                    right.set_pose((x[0] + 1e-5, x[1], x[2]))
                scene.step()
            return scene.suture.centerline()
        finally:
            scene.close()

    assert np.array_equal(run(), run())


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"robots": {}}, "robots"),
        ({"suture": {"knot": "bowline"}}, "suture.knot"),
        ({"tools": {"left": "scalpel"}}, "tools.left"),
        ({"tissue": {"entry": [0, 0]}}, "tissue.entry"),
        ({"tools": {"a": "grasper", "b": "grasper", "c": "grasper"}}, "tools"),
    ],
)
def test_bad_dict_scenes_are_typed_errors(config: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(SceneError) as err:
        build_scene(config)
    assert err.value.field == field
