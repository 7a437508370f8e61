"""Physics-only real-time factor of the suture scene, and the thread's stretch under load.

Run: ``python benchmarks/scene_rtf.py``. The physics rate is the runtime's control rate,
1 kHz (``backends.pybullet.suture.PHYSICS_RATE``). For 40, 60 and 80 segments a 0.3 m thread
is held at one end by a grasper and pulled at the other by a constant 0.5 N force for 5 s of
simulated time; the script prints the real-time factor (simulated time / wall time, one
process, one core) and the stretch (joint gaps / rest length) at the end.
"""

from __future__ import annotations

import time


def run(segments: int, seconds: float = 5.0, load: float = 0.5) -> tuple[float, float]:
    """Real-time factor [-] and stretch [-] of a thread with ``segments`` capsules."""
    import pybullet as p

    from backends.pybullet.suture import (
        PHYSICS_RATE,
        Suture,
        SutureParams,
        configure_physics,
        straight_path,
    )

    c = p.connect(p.DIRECT)
    try:
        configure_physics(c)
        sut = Suture.create(
            c,
            straight_path((0.0, 0.0, 0.1), (1.0, 0.0, 0.0), 0.3),
            SutureParams(n_segments=segments),
        )
        anchor = p.createConstraint(
            sut.bodies[0],
            -1,
            -1,
            -1,
            p.JOINT_POINT2POINT,
            [0, 0, 0],
            [0, 0, -sut.params.segment_length / 2],
            [0.0, 0.0, 0.1],
            physicsClientId=c,
        )
        del anchor
        last = sut.needle_body
        steps = int(seconds * PHYSICS_RATE)
        t0 = time.perf_counter()
        for _ in range(steps):
            sut.pre_step()
            pos, _ = p.getBasePositionAndOrientation(last, physicsClientId=c)
            p.applyExternalForce(last, -1, [load, 0, 0], pos, p.WORLD_FRAME, physicsClientId=c)
            p.stepSimulation(physicsClientId=c)
        wall = time.perf_counter() - t0
        return seconds / wall, sut.stretch()
    finally:
        p.disconnect(physicsClientId=c)


def main() -> None:
    """Print the figures."""
    print("physics rate 1000 Hz, thread 0.3 m, pull 0.5 N at the needle, 5 s simulated")
    print(f"{'segments':>8} {'RTF':>7} {'stretch':>8}")
    for n in (40, 60, 80):
        rtf, stretch = run(n)
        print(f"{n:>8} {rtf:>6.2f}x {100 * stretch:>7.2f}%")


if __name__ == "__main__":
    main()
