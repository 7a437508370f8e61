"""Algorithm 1's failure analysis (thesis 4.4.1): its step 4 against the knot's position.

The thesis: "In Step 4, a large angle is required between the two instruments.
For knots near the center of the workspace, this may not be feasible." For knot
positions along the wound (x) and across it (y) on the bench scene, this plans
steps 2-4 as the procedure does, with the skills' own geometry:

* step 2: the grasper holds the tail 8 mm beyond the entry point (entry = knot - 4 mm
  in y), 2 mm above the tissue;
* step 3: :func:`skills.rotate_about.stem_contact` puts the stitcher's open jaw
  2 mm off the front (first throw) or back (mirrored throw) of the grasper stem, as
  far up the stem as the workspace allows (the highest of 40, 35, ..., 10 mm whose
  pose and rotation stay in the joint limits, else the one with the fewest
  problems);
* step 4: ``rotate-about`` by +180 deg (mirror: -180 deg) about OP is planned on
  an ideal tracker: the joint-limit check of its path and the clearance of the
  needle tip (the thesis' condition), of the whole needle and of the stitcher's
  tip body from the grasper stem (:func:`skills.rotate_about.sweep_clearance`).

It prints one row per position and throw: the angle between the instruments at
step 4, the contact height, the stitcher's roll there, whether the path keeps the
joint limits, the three clearances [mm], and two verdicts: ``thesis`` (joint
limits kept and the needle tip clear by 1 mm) and ``tool`` (also the needle and
the tip body clear: what the bundled stitcher would need). No physics: this is
the kinematic model and the declared tool geometry. On ``pybullet-surgical`` at the
bench's default knot: while the stitcher's jaws did not collide, the rotation
completed with the needle brushing the grasper stem (about 0.9 N on both base
sensors); with colliding jaws it pressed the tools together until the tension
emergency (6.36 N), as the ``needle`` column predicts.

    python benchmarks/alg1_position.py [--x -60,-40,...] [--y -20,0,20]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

HEIGHTS = (0.04, 0.035, 0.03, 0.025, 0.02, 0.015, 0.01)
"""Contact heights up the grasper stem tried, highest first [m]."""
CLEARANCE = 1e-3
"""Required clearance [m]."""
JAW_GAP = 2e-3
"""Open jaw's centre to the stem's surface at the contact [m], as knot-algorithm-1.yaml."""


class Row(NamedTuple):
    """One planned step 4."""

    x: float
    y: float
    throw: str
    angle: float
    height: float
    roll: float
    limits: str
    tip: float
    needle: float
    tool: float


def _base(scene: Any, robot: str) -> tuple[Any, Any]:
    from scipy.spatial.transform import Rotation

    spec = scene.robots[robot].base
    rot = Rotation.from_euler("xyz", spec.rpy).as_matrix()
    return tuple(spec.position), tuple(rot.reshape(-1))


def _within(scene: Any, robot: str, q: Any) -> str:
    jl = scene.robots[robot].joint_limits
    box = [jl.yaw, jl.pitch, jl.roll, jl.insertion]
    names = ("yaw", "pitch", "roll", "insertion")
    for i, (lo, hi) in enumerate(box):
        if not lo - 1e-9 <= q[i] <= hi + 1e-9:
            return f"{names[i]} {q[i]:.3g} outside [{lo:.3g}, {hi:.3g}]"
    return ""


def plan(scene: Any, x: float, y: float, mirror: bool, half_spacing: float | None = None) -> Row:
    """Plan steps 2-4 for the knot at (x, y) [m]; the mirrored throw when ``mirror``.

    ``half_spacing`` [m] puts the two RCM points (ports) at x = -/+ it instead of
    where the scene declares them.
    """
    from skills.rotate_about import RotateAbout, RotateAboutParams, stem_contact
    from skills.tool_path import ik_world
    from suture_engine.runtime.context import SkillContext
    from suture_engine.runtime.observation import (
        Observation,
        RobotObservation,
        SceneGeometry,
        ToolState,
    )

    b1, b2 = _base(scene, "endobot_1"), _base(scene, "endobot_2")
    if half_spacing is not None:
        b1 = ((-half_spacing, *b1[0][1:]), b1[1])
        b2 = ((half_spacing, *b2[0][1:]), b2[1])
    t2 = np.array((x, y - 0.012, 0.002))
    o2 = np.array(b2[0])
    q2 = ik_world(t2, 0.0, b2)
    side, angle = (-1.0, -math.pi) if mirror else (1.0, math.pi)
    throw = "mirror" if mirror else "first"
    grasper_problem = _within(scene, "endobot_2", q2)
    best: tuple[int, Row] | None = None
    for h in HEIGHTS:
        c = stem_contact(b1, (t2, o2), h, side, 2.5e-3, jaw_half_width=JAW_GAP)
        problems = _within(scene, "endobot_1", c.joints) or grasper_problem
        clear: dict[str, float] = {}
        for swept in ("needle-tip", "needle", "tool"):
            params = RotateAboutParams.model_validate(
                {
                    "robot": "stitcher",
                    "angle": angle,
                    "relative_to": "grasper",
                    "point": tuple(c.contact - t2),
                    "clear_of": "grasper",
                    "clearance": 0.0,
                    "swept": swept,
                }
            )
            tools = {
                "endobot_1": ToolState("stitcher", True),
                "endobot_2": ToolState("grasper", True),
            }
            obs = Observation(
                0,
                0.0,
                {
                    n: RobotObservation(np.asarray(q, float), np.zeros(4), np.zeros(6), tools[n])
                    for n, q in (("endobot_1", c.joints), ("endobot_2", q2))
                },
                SceneGeometry(),
            )
            roles = {"stitcher": "endobot_1", "grasper": "endobot_2"}
            ctx = SkillContext(
                "rotate", roles, 1e-3, obs, scene, {}, {"endobot_1": b1, "endobot_2": b2}
            )
            skill = RotateAbout(params)
            skill.start(ctx)
            assert skill.clearance is not None
            clear[swept] = skill.clearance.distance
            path_problem = skill.limit_violation
            instr = skill.clearance.instrument_angle
        problems = problems or path_problem
        row = Row(
            x,
            y,
            throw,
            math.degrees(instr),
            h,
            math.degrees(float(c.joints[2])),
            problems or "ok",
            clear["needle-tip"],
            clear["needle"],
            clear["tool"],
        )
        score = 0 if not problems else 1
        if best is None or score < best[0]:
            best = (score, row)
        if not problems:
            break
    assert best is not None
    return best[1]


def main(argv: list[str] | None = None) -> int:
    """Print the table; returns 0."""
    from suture_engine.language.loader import load_procedure

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", default="-90,-60,-30,0,30,60,90", help="knot x [mm]")
    ap.add_argument("--y", default="-40,0,40", help="knot y [mm]")
    ap.add_argument(
        "--ports",
        default="70,40,20",
        help="half the distance between the two RCM points along x [mm] (the bench: 70)",
    )
    args = ap.parse_args(argv)
    scene = load_procedure(ROOT / "procedures" / "knot-algorithm-1.yaml").scene
    xs = [float(v) * 1e-3 for v in args.x.split(",")]
    ys = [float(v) * 1e-3 for v in args.y.split(",")]
    for half in (float(v) * 1e-3 for v in args.ports.split(",")):
        print(f"\nRCM points at x = -/+{half * 1e3:.0f} mm, y = -50 mm, z = 120 mm")
        table(scene, xs, ys, half)
    return 0


def table(scene: Any, xs: list[float], ys: list[float], half: float) -> None:
    """Print one table of positions for RCM points at x = -/+ ``half`` [m]."""
    head = (
        f"{'x mm':>5} {'y mm':>5} {'angle deg':>9} {'P up mm':>7} {'roll deg':>13} "
        f"{'tip clear mm':>13} {'needle mm':>11} {'thesis':>6} {'tool':>5}  joints"
    )
    print("first throw / mirrored throw; clearances from the grasper stem's surface")
    print(head)
    print("-" * len(head))
    counts = {"thesis": 0, "tool": 0, "n": 0}
    for y in ys:
        for x in xs:
            a, b = plan(scene, x, y, False, half), plan(scene, x, y, True, half)
            verdicts = []
            for r in (a, b):
                thesis = r.limits == "ok" and r.tip >= CLEARANCE
                tool = thesis and min(r.needle, r.tool) >= CLEARANCE
                counts["thesis"] += thesis
                counts["tool"] += tool
                counts["n"] += 1
                verdicts.append(("yes" if thesis else "no", "yes" if tool else "no"))
            limits = a.limits if a.limits == b.limits else f"{a.limits} / {b.limits}"
            print(
                f"{x * 1e3:5.0f} {y * 1e3:5.0f} {a.angle:9.1f} "
                f"{a.height * 1e3:3.0f}/{b.height * 1e3:<3.0f} "
                f"{a.roll:6.1f}/{b.roll:<6.1f} {a.tip * 1e3:6.2f}/{b.tip * 1e3:<6.2f} "
                f"{min(a.needle, a.tool) * 1e3:5.2f}/{min(b.needle, b.tool) * 1e3:<5.2f} "
                f"{verdicts[0][0]:>3}/{verdicts[1][0]:<3} {verdicts[0][1]:>3}/{verdicts[1][1]:<3} "
                f"{limits}"
            )
    n = counts["n"]
    print(
        f"\nthrows feasible by the thesis' condition (joint limits kept, needle tip clear by "
        f"{CLEARANCE * 1e3:.0f} mm): {counts['thesis']}/{n}; also with the bundled stitcher's "
        f"whole needle and tip body clear: {counts['tool']}/{n}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
