"""Physics-only real-time factor of the suture scene, and the thread's stretch under load.

Run: ``python benchmarks/scene_rtf.py``. The physics rate is the runtime's control rate,
1 kHz (``backends.pybullet.suture.PHYSICS_RATE``). For 40, 60 and 80 segments a 0.3 m
thread is held at one end and pulled at the needle by a constant 0.5 N for 5 s of
simulated time; the script prints the real-time factor (simulated time over wall time,
and over the process's CPU time, the fairer figure when other jobs share the machine;
one process, one core) and the stretch (joint gaps over rest length) at the end. It then
times ``Scene.step`` on the default scene (40-segment thread with needle, tissue pad, two
graspers) and on the bench scene of ``procedures/scenes/bench.yaml`` (two EndoBots held
still, stitcher, hook grasper).
"""

from __future__ import annotations

import time


def run(segments: int, seconds: float = 5.0, load: float = 0.5) -> tuple[float, float, float]:
    """Real-time factors (wall, CPU) [-] and stretch [-] of a thread of ``segments`` capsules."""
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
        c0 = time.process_time()
        t0 = time.perf_counter()
        for _ in range(steps):
            sut.pre_step()
            pos, _ = p.getBasePositionAndOrientation(last, physicsClientId=c)
            p.applyExternalForce(last, -1, [load, 0, 0], pos, p.WORLD_FRAME, physicsClientId=c)
            p.stepSimulation(physicsClientId=c)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
        return seconds / wall, seconds / cpu, sut.stretch()
    finally:
        p.disconnect(physicsClientId=c)


def run_scene(config: object, seconds: float = 3.0) -> tuple[float, float]:
    """Real-time factors (wall, CPU) [-] of ``Scene.step`` on a built scene."""
    from backends.pybullet.scene import build_scene

    scene = build_scene(config)
    try:
        steps = int(seconds * 1000)
        c0 = time.process_time()
        t0 = time.perf_counter()
        for _ in range(steps):
            scene.step()
        return seconds / (time.perf_counter() - t0), seconds / (time.process_time() - c0)
    finally:
        scene.close()


def main() -> None:
    """Print the figures."""
    print("physics rate 1000 Hz, thread 0.3 m, pull 0.5 N at the needle, 5 s simulated")
    print(f"{'segments':>8} {'RTF wall':>9} {'RTF CPU':>8} {'stretch':>8}")
    for n in (40, 60, 80):
        wall, cpu, stretch = run(n)
        print(f"{n:>8} {wall:>8.2f}x {cpu:>7.2f}x {100 * stretch:>7.2f}%")
    wall, cpu = run_scene({})
    print(f"default scene (thread, tissue, 2 graspers): {wall:.2f}x wall, {cpu:.2f}x CPU")
    from pathlib import Path

    import yaml

    from suture_engine.language.scene import Scene

    bench = Path(__file__).resolve().parent.parent / "procedures/scenes/bench.yaml"
    model = Scene.model_validate(yaml.safe_load(bench.read_text()))
    wall, cpu = run_scene(model)
    print(f"bench scene (2 EndoBots, stitcher, hook grasper): {wall:.2f}x wall, {cpu:.2f}x CPU")


if __name__ == "__main__":
    main()
