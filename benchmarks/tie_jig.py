"""Knots tied by tool motion on the peg jig: what the classifier says and how they hold.

Run: ``python benchmarks/tie_jig.py [--frames DIR]``. Ties, from a straight thread, the
overhand knot (right-handed, and mirrored) on a 0.3 m, 60-segment thread and the two-throw
knots (opposite throws, like throws) on a 0.5 m, 100-segment thread
(:func:`backends.pybullet.tying.tie_on_jig`), then prints per case the classifier's type,
determinant, v2 and v3 on the final ground-truth centerline, the time to reach 2 N, the
smallest and the settled grip force during the 1 s hold [N], the largest stretch [%], the
end-to-end span [m] and the CPU time. With ``--frames`` it writes a PNG per phase.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


def main(frames: Path | None = None) -> None:
    """Run the four cases and print one line each."""
    from backends.pybullet.render import Camera, render_frame, save_png
    from backends.pybullet.tying import JigTie, tie_on_jig
    from suture_engine.suture.topology import classify_knot

    short = JigTie()
    long = JigTie(length=0.5, segments=100, first_offset=0.16)
    cases = [
        ("overhand", (False,), short),
        ("overhand-mirrored", (True,), short),
        ("two opposite throws", (False, True), long),
        ("two like throws", (False, False), long),
    ]
    print(
        f"{'case':22s} {'type':16s} det v2 v3  t2N[s] min[N] settled[N] stretch[%] span[m] cpu[s]"
    )
    for name, throws, jig in cases:
        shots: list[str] = []

        def snap(phase: str, client: int, name: str = name, shots: list[str] = shots) -> None:
            if frames is None:
                return
            cam = Camera(target=(-0.12, 0.01, 0.02), distance=0.3, yaw=0, pitch=-80)
            path = frames / f"{name.replace(' ', '-')}-{len(shots)}-{phase}.png"
            save_png(render_frame(client, cam), path)
            shots.append(str(path))

        t0 = time.process_time()
        result = tie_on_jig(throws, jig, snap)
        cpu = time.process_time() - t0
        rep = classify_knot(result.final)
        kind = rep.type + (f" ({rep.chirality})" if rep.chirality else "")
        pull = result.pull
        print(
            f"{name:22s} {kind:16s} {rep.determinant:3d} {rep.v2:2d} {rep.v3:2d} "
            f"{pull.time_to_target:7.2f} {pull.min_hold_force:6.2f} {pull.settled_force:10.2f} "
            f"{100 * pull.max_stretch:10.2f} {result.span:7.3f} {cpu:6.1f}"
        )


if __name__ == "__main__":
    out = None
    if len(sys.argv) == 3 and sys.argv[1] == "--frames":
        out = Path(sys.argv[2])
        out.mkdir(parents=True, exist_ok=True)
    main(out)
