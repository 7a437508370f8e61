"""hold and move-to on the PyBullet robot, checked against PyBullet's own tool-link state."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from backends.pybullet.backend import PyBulletBackend
from suture_engine.runtime.interpreter import Interpreter
from suture_engine.runtime.run import load_plan

PROCS = Path(__file__).resolve().parent / "procedures"


def test_move_to_reaches_the_target_in_the_simulator() -> None:
    proc, plan = load_plan(PROCS / "reach.yaml", ["speed=100 mm/s"])
    be = PyBulletBackend()
    try:
        first = be.reset(proc.scene, 0)
        it = Interpreter(
            plan, be, first, roles=proc.roles, params=proc.params, scene=proc.scene, max_time_s=10
        )
        tips: dict[str, np.ndarray] = {}
        while it.tick():
            step = it.automaton.step_name
            if step is not None:  # the true tip while each step runs (last tick wins)
                tips[step] = np.array(be.ground_truth()["endobot_1/tool_tip"])
        assert it.automaton.state == "finished"
        entry = np.array(proc.scene.tissue.points["entry"])
        final = np.array(be.ground_truth()["endobot_1/tool_tip"])
        # PyBullet's link state, not our kinematics: within move-to's 0.5 mm tolerance
        assert np.linalg.norm(final - (entry + np.array([0.0, 0.0, 0.06]))) < 0.5e-3
        assert np.linalg.norm(tips["settle"] - (entry + np.array([0.0, 0.0, 0.04]))) < 0.5e-3
    finally:
        be.close()
