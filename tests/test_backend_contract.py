"""One backend contract, written once and run against every backend (only the fixture changes)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from backends import registry
from backends.base import Backend, BackendError
from suture_engine.runtime.observation import (
    Command,
    CommandMode,
    Measurement,
    RobotCommand,
    SceneGeometry,
)

HERE = Path(__file__).resolve().parent

SCENE = SimpleNamespace(
    robots={
        "endobot_1": SimpleNamespace(
            base=SimpleNamespace(position=(-0.05, 0.0, 0.12), rpy=(math.pi, 0.0, 0.0)),
            tool="stitcher",
        ),
        "endobot_2": SimpleNamespace(
            base=SimpleNamespace(position=(0.05, 0.0, 0.12), rpy=(math.pi, 0.0, 0.0)),
            tool="grasper",
        ),
    },
    tissue=SimpleNamespace(points={"entry": (-0.004, 0.0, 0.0)}, normal=(0.0, 0.0, 1.0)),
)


def _torques(meas: Measurement, k: int) -> Command:
    """A deterministic small torque pattern (gravity is not compensated: the arms move)."""
    return Command(
        {
            name: RobotCommand(CommandMode.TORQUE, tau=0.01 * np.sin(k + np.arange(4)))
            for name in meas.robots
        }
    )


def _drive(backend: Any, seed: int, ticks: int) -> list[Measurement]:
    out = [backend.reset(SCENE, seed)]
    for k in range(ticks):
        backend.apply(_torques(out[-1], k))
        backend.step()
        out.append(backend.observe())
    return out


class BackendContract:
    """The contract every backend meets. Subclasses provide the ``backend`` fixture."""

    ticks = 20

    def test_is_a_backend(self, backend: Any) -> None:
        assert isinstance(backend, Backend)
        assert isinstance(backend.name, str) and backend.name

    def test_reset_measures_two_endobots(self, backend: Any) -> None:
        meas = backend.reset(SCENE, 0)
        assert isinstance(meas, Measurement)
        assert (meas.tick, meas.t) == (0, 0.0)
        assert sorted(meas.robots) == ["endobot_1", "endobot_2"]
        for robot in meas.robots.values():
            assert robot.q.shape == (4,) and robot.base_wrench.shape == (6,)
            assert np.all(np.isfinite(robot.q)) and np.all(np.isfinite(robot.base_wrench))
            assert not robot.q.flags.writeable

    def test_step_advances_one_control_period(self, backend: Any) -> None:
        ms = _drive(backend, 0, self.ticks)
        assert [m.tick for m in ms] == list(range(self.ticks + 1))
        assert ms[-1].t == pytest.approx(self.ticks * 1e-3)

    def test_same_seed_same_measurements(self, backend: Any) -> None:
        a = _drive(backend, 3, self.ticks)
        b = _drive(backend, 3, self.ticks)
        for ma, mb in zip(a, b, strict=True):
            for name in ma.robots:
                np.testing.assert_array_equal(ma.robots[name].q, mb.robots[name].q)
                np.testing.assert_array_equal(
                    ma.robots[name].base_wrench, mb.robots[name].base_wrench
                )

    def test_geometry_and_ground_truth_stay_apart(self, backend: Any) -> None:
        meas = backend.reset(SCENE, 0)
        assert isinstance(backend.geometry(), SceneGeometry)
        truth = backend.ground_truth()
        assert hasattr(truth, "keys")
        for robot in meas.robots.values():
            assert set(vars(robot)) == {"q", "base_wrench", "tool", "fault"}

    def test_tool_commands_and_forces_are_accepted(self, backend: Any) -> None:
        from suture_engine.runtime.observation import ToolCommand

        meas = backend.reset(SCENE, 0)
        cmd = Command(
            {
                n: RobotCommand(CommandMode.TORQUE, tau=np.zeros(4), tool=ToolCommand(True))
                for n in meas.robots
            }
        )
        backend.apply_external_force("endobot_1", (0.0, 0.0, 0.1), 0.002)
        backend.apply(cmd)
        backend.step()
        assert backend.observe().tick == 1

    def test_close_is_idempotent(self, backend: Any) -> None:
        backend.reset(SCENE, 0)
        backend.close()
        backend.close()


class TestPyBulletBackend(BackendContract):
    @pytest.fixture
    def backend(self) -> Iterator[Any]:
        be = registry.create("pybullet")
        yield be
        be.close()

    def test_torques_only(self, backend: Any) -> None:
        meas = backend.reset(SCENE, 0)
        with pytest.raises(BackendError):
            backend.apply(Command({"endobot_1": RobotCommand.position(meas.robots["endobot_1"].q)}))

    def test_base_sensor_reads_the_weight_at_rest(self, backend: Any) -> None:
        meas = backend.reset(SCENE, 0)
        from backends.pybullet.urdf import endobot_urdf  # noqa: F401  (the model's URDF)

        sim = backend.robots["endobot_1"]
        import pybullet as p

        mass = sum(
            p.getDynamicsInfo(sim.body_id, j, physicsClientId=backend.client)[0]
            for j in range(-1, p.getNumJoints(sim.body_id, physicsClientId=backend.client))
        )
        base_mass = p.getDynamicsInfo(sim.body_id, -1, physicsClientId=backend.client)[0]
        force = np.linalg.norm(meas.robots["endobot_1"].base_wrench[:3])
        # the sensor carries everything beyond the fixed base
        assert force == pytest.approx((mass - base_mass) * 9.81, rel=0.02)


class TestReplayBackend(BackendContract):
    @pytest.fixture(scope="class")
    def recording(self, tmp_path_factory: pytest.TempPathFactory) -> Path:
        from suture_engine.runtime.run import run_procedure

        out = tmp_path_factory.mktemp("recording")
        run_procedure(HERE / "procedures" / "steps.yaml", backend="pybullet", out=out)
        return out / "trace.mcap"

    @pytest.fixture
    def backend(self, recording: Path) -> Iterator[Any]:
        be = registry.create("replay", trace=recording)
        yield be
        be.close()

    def test_serves_the_recorded_positions(self, backend: Any, recording: Path) -> None:
        from suture_engine.trace.reader import TraceReader

        ms = _drive(backend, 0, 5)
        recorded = [
            m.data["position"] for m in TraceReader(recording).messages(["/joint_state/endobot_2"])
        ]
        for k in range(6):
            assert list(ms[k].robots["endobot_2"].q) == recorded[k]

    def test_end_of_recording_is_a_typed_error(self, backend: Any) -> None:
        from backends.replay import EndOfRecording

        backend.reset()
        backend.tick = backend.last_tick + 1
        assert backend.exhausted
        with pytest.raises(EndOfRecording):
            backend.observe()


class TestIdealBackend(BackendContract):
    @pytest.fixture
    def backend(self) -> Iterator[Any]:
        be = registry.create("ideal")
        yield be
        be.close()


def test_unknown_backend_suggests_names() -> None:
    with pytest.raises(registry.UnknownBackend) as err:
        registry.create("pybulet")
    assert err.value.suggestions[0] == "pybullet"
    assert {"pybullet", "replay", "ideal"} <= set(registry.available())


def test_known_names_need_no_entry_point_scan(monkeypatch: pytest.MonkeyPatch) -> None:
    scans: list[str] = []

    def fake_entry_points(group: str) -> list[Any]:
        scans.append(group)
        return [SimpleNamespace(name="third-party")]

    monkeypatch.setattr(registry, "entry_points", fake_entry_points)
    monkeypatch.setattr(registry, "_SCANNED", None)
    assert registry.is_known("pybullet") and registry.is_known("ideal")
    assert scans == []
    assert registry.is_known("third-party")
    assert not registry.is_known("pybulet")
    assert "third-party" in registry.available()
    # one scan per process, however many names are looked up
    assert scans == [registry.ENTRY_POINT_GROUP]


def test_pybullet_force_noise_and_delay_follow_the_scene_and_the_seed() -> None:
    noisy = SimpleNamespace(
        **vars(SCENE), physics=SimpleNamespace(force_noise=0.05, measurement_delay=0.003)
    )
    be = registry.create("pybullet")
    try:
        runs = {}
        for seed in (1, 1, 2):
            ms = [be.reset(noisy, seed)]
            for k in range(10):
                be.apply(_torques(ms[-1], k))
                be.step()
                ms.append(be.observe())
            runs.setdefault(seed, []).append(
                np.array([m.robots["endobot_1"].base_wrench for m in ms])
            )
        np.testing.assert_array_equal(runs[1][0], runs[1][1])  # same seed, same noise
        assert np.abs(runs[1][0] - runs[2][0])[5:, :3].max() > 1e-3  # another seed differs
        ideal = _drive(be, 1, 10)
        clean = np.array([m.robots["endobot_1"].base_wrench for m in ideal])
        noise = (runs[1][0] - clean)[5:, :3]
        assert 0.01 < float(noise.std()) < 0.2  # about the declared 0.05 N
    finally:
        be.close()
