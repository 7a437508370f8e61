"""Where a ``move-to`` leaves the robot, against where it was sent, under joint friction.

Runs a small procedure on the two robots (``pybullet`` by default, no thread) for each
joint-friction scale (the perturbation of ``benchmarks/knot_success.py``, ±30 %):

1. the grasper rolls half a turn in place (``roll: 180 deg``, ``roll_tolerance: 5 deg``,
   as ``hook-up`` in ``knot-algorithm-2.yaml``), then holds 2 s;
2. the stitcher moves 28 mm, sideways and down (10 mm/s, ``tolerance: 0.5 mm``), then holds 2 s.

Printed per scale, from the trace's joint states (encoders; the roll joint is the tool's
roll, q3):

- the roll's shortfall of the half turn when the move ends, and after the hold;
- the tool tip's distance from the move's goal (forward kinematics of the encoders,
  through the declared base) when the move ends, and after the hold.

``move-to`` ends once the roll is within its 3 deg tolerance (or, after the settling
time, ``roll_tolerance``); the hold that follows keeps the pose where the move ended, so
the shortfall stays.

Usage::

    python benchmarks/settle_error.py [--scales 0.7,1.0,1.3] [--backend pybullet]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import shutil
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "procedures" / "scenes" / "bench.yaml"
GRASPER, STITCHER = "endobot_2", "endobot_1"
MOVE = (0.020, 0.0, -0.020)
"""The stitcher's move from its start [m] (world frame): sideways and down. (Up, from the
vertical start, the insertion motor's 2.47 N at 10 V barely exceeds the tool's 2.40 N
weight: with nominal friction the tool does not rise.)"""

PROCEDURE = """\
procedure: settle-error
version: "1"
description: A half-turn roll of the grasper and a 28 mm move of the stitcher, each held.
scene: scene.yaml
roles: {stitcher: endobot_1, grasper: endobot_2}
initial: roll
states:
  roll:
    skill: move-to
    with: {robot: grasper, relative_to: grasper, target: [0 mm, 0 mm, 0 mm], roll: 180 deg,
           roll_tolerance: 5 deg, speed: 10 mm/s, tolerance: 2 mm}
    timeout: 10 s
    "on": {done: roll-held, failed: {retry: 0, then: abort}}
  roll-held:
    skill: hold
    with: {robot: grasper, duration: 2 s}
    "on": {done: move, failed: {retry: 0, then: abort}}
  move:
    skill: move-to
    with: {robot: stitcher, relative_to: stitcher, target: [MOVE_MM], speed: 10 mm/s,
           tolerance: 0.5 mm}
    timeout: 10 s
    "on": {done: move-held, failed: {retry: 0, then: abort}}
  move-held:
    skill: hold
    with: {robot: stitcher, duration: 2 s}
    "on": {done: finished, failed: {retry: 0, then: abort}}
  finished: {outcome: succeeded}
"""


def _joints_at_entries(
    trace: Path,
) -> tuple[dict[str, dict[str, list[float]]], dict[str, list[float]]]:
    """Each robot's encoder joints when each state was entered, and at the trace's end."""
    from suture_engine.trace.reader import TraceReader

    last: dict[str, list[float]] = {}
    at: dict[str, dict[str, list[float]]] = {}
    topics = ["/transitions", f"/joint_state/{GRASPER}", f"/joint_state/{STITCHER}"]
    for m in TraceReader(trace).messages(topics):
        if m.topic == "/transitions":
            at[m.data["dest"].split("/")[-1]] = dict(last)
        else:
            last[m.topic.rsplit("/", 1)[-1]] = list(m.data["position"])
    return at, last


def measure(scale: float, backend: str, work: Path) -> tuple[float, float, float, float]:
    """(roll shortfall at the move's end, after the hold [deg], tip error at the move's
    end, after the hold [mm]) for one friction scale."""
    from suture_engine.language.loader import load_procedure
    from suture_engine.runtime.run import run_procedure
    from suture_engine.runtime.trajectory import rpy_matrix, tool_tip_world

    out = work / f"out-{scale:g}"
    with contextlib.redirect_stdout(io.StringIO()):
        result = run_procedure(
            str(work / "procedure.yaml"),
            backend=backend,
            seed=0,
            out=out,
            max_time_s=40.0,
            backend_options={"friction_scale": scale},
        )
    if result.summary.outcome != "succeeded":
        raise SystemExit(
            f"friction x{scale:g}: the procedure ended {result.summary.outcome} "
            f"({result.summary.final_state}: {result.summary.metrics.get('stopped', '')})"
        )
    at, end = _joints_at_entries(out / "trace.mcap")
    roll_end = 180.0 - math.degrees(at["roll-held"][GRASPER][2])
    roll_held = 180.0 - math.degrees(at["move"][GRASPER][2])
    scene = load_procedure(work / "procedure.yaml").scene
    assert scene is not None
    spec = scene.robots[STITCHER].base
    base = (tuple(spec.position), tuple(float(v) for v in rpy_matrix(spec.rpy)))
    start = tool_tip_world(np.array(at["move"][STITCHER]), base)
    goal = start + np.array(MOVE)
    tip_end = 1e3 * float(
        np.linalg.norm(tool_tip_world(np.array(at["move-held"][STITCHER]), base) - goal)
    )
    tip_held = 1e3 * float(np.linalg.norm(tool_tip_world(np.array(end[STITCHER]), base) - goal))
    return roll_end, roll_held, tip_end, tip_held


def main(argv: Sequence[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--scales", default="0.7,1.0,1.3", help="joint-friction scales, comma-separated"
    )
    ap.add_argument("--backend", default="pybullet")
    args = ap.parse_args(argv)
    scales = [float(s) for s in args.scales.split(",")]
    work = Path(tempfile.mkdtemp(prefix="settle-error-"))
    try:
        shutil.copy(SCENE, work / "scene.yaml")
        target = ", ".join(f"{v * 1e3:g} mm" for v in MOVE)
        (work / "procedure.yaml").write_text(PROCEDURE.replace("MOVE_MM", target))
        print(f"backend {args.backend}; roll: grasper, half a turn; move: stitcher, 28 mm")
        heads = ("friction", "roll short, end", "after hold", "tip error, end", "after hold")
        print(" ".join(f"{h:>{w}}" for h, w in zip(heads, (9, 16, 11, 15, 11), strict=True)))
        for s in scales:
            r_end, r_held, t_end, t_held = measure(s, args.backend, work)
            scale = f"x{s:g}"
            print(
                f"{scale:>9} {r_end:12.2f} deg {r_held:7.2f} deg {t_end:12.3f} mm {t_held:8.3f} mm"
            )
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
