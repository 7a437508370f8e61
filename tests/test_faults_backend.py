"""FaultyBackend: the backend contract, and each fault checked against the clean backend.

The oracle is the same backend run without the wrapper, driven with the same
commands: a bias is the exact difference, a delay is the clean value some ticks
earlier, a dropout repeats the last value, noise has the declared standard
deviation, joint faults are read on the torques the inner backend receives.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from test_backend_contract import SCENE, BackendContract

from suture_engine.faults.backend import ENERGY_CAP_N, FaultyBackend
from suture_engine.faults.model import Fault
from suture_engine.faults.support import FaultNotSupported
from suture_engine.runtime.observation import Command, Measurement, RobotCommand
from suture_engine.runtime.testing import IdealBackend

N = 40


class TestFaultyIdealBackend(BackendContract):
    """The wrapper meets the contract (noise and bias on, deterministic for a seed)."""

    @pytest.fixture
    def backend(self) -> Iterator[Any]:
        faults = [
            Fault(kind="noise", sensor="ft", value=0.05),
            Fault(kind="noise", sensor="encoders", value=1e-4, at=0.005),
            Fault(kind="bias", sensor="ft", value=0.3, axis="x"),
        ]
        be = FaultyBackend(IdealBackend(), faults)
        yield be
        be.close()


class TestFaultyPyBulletBackend(BackendContract):
    @pytest.fixture
    def backend(self) -> Iterator[Any]:
        from backends import registry

        faults = [
            Fault(kind="delay", sensor="ft", value=0.002),
            Fault(kind="noise", sensor="ft", value=0.02),
        ]
        be = FaultyBackend(registry.create("pybullet"), faults, backend_name="pybullet")
        yield be
        be.close()


class Spy(IdealBackend):
    """An ideal backend that keeps the torques it was given and the hooks called."""

    name = "spy"

    def __init__(self) -> None:
        super().__init__()
        self.applied: list[dict[str, np.ndarray]] = []
        self.pushes: list[tuple[int, str, tuple[float, float, float], float]] = []
        self.slips: list[tuple[int, str]] = []
        self.snags: list[tuple[int, float, float]] = []

    def apply(self, command: Command) -> None:
        self.applied.append({n: np.array(rc.tau) for n, rc in command.robots.items()})
        super().apply(command)

    def apply_external_force(
        self, robot: str, force: tuple[float, float, float], duration: float
    ) -> None:
        self.pushes.append((self.tick, robot, force, duration))
        super().apply_external_force(robot, force, duration)

    def inject_grasp_slip(self, robot: str) -> None:
        self.slips.append((self.tick, robot))

    def inject_snag(self, extra_friction_N: float, duration_s: float) -> None:
        self.snags.append((self.tick, extra_friction_N, duration_s))


def _tau(k: int) -> Command:
    return Command(
        {
            r: RobotCommand.torque(0.02 * np.sin(0.1 * k + np.arange(4)))
            for r in ("endobot_1", "endobot_2")
        }
    )


def _lockstep(
    faults: list[Fault], ticks: int = N, seed: int = 0, inner: Any = None
) -> tuple[list[Measurement], list[Measurement], FaultyBackend]:
    clean = IdealBackend()
    faulty = FaultyBackend(inner if inner is not None else IdealBackend(), faults)
    a, b = [clean.reset(SCENE, seed)], [faulty.reset(SCENE, seed)]
    for k in range(ticks):
        clean.apply(_tau(k))
        faulty.apply(_tau(k))
        clean.step()
        faulty.step()
        a.append(clean.observe())
        b.append(faulty.observe())
    return a, b, faulty


def _w(ms: list[Measurement], robot: str = "endobot_1") -> np.ndarray:
    return np.array([m.robots[robot].base_wrench for m in ms])


def _q(ms: list[Measurement], robot: str = "endobot_1") -> np.ndarray:
    return np.array([m.robots[robot].q for m in ms])


def test_bias_is_added_from_its_onset_on_the_named_robot_only() -> None:
    a, b, _ = _lockstep([Fault(kind="bias", sensor="ft", robot="endobot_1", value=0.5, at=0.01)])
    diff = _w(b) - _w(a)
    np.testing.assert_allclose(diff[:10], 0.0, atol=0)
    np.testing.assert_allclose(diff[10:, 2], 0.5, rtol=0, atol=1e-12)
    np.testing.assert_allclose(diff[10:, [0, 1, 3, 4, 5]], 0.0, atol=0)
    np.testing.assert_array_equal(_w(b, "endobot_2"), _w(a, "endobot_2"))


def test_encoder_bias_in_metres_is_the_insertions() -> None:
    a, b, _ = _lockstep(
        [Fault.model_validate({"kind": "bias", "sensor": "encoders", "value": "2 mm"})]
    )
    diff = _q(b) - _q(a)
    np.testing.assert_allclose(diff[:, 3], 0.002, atol=1e-12)
    np.testing.assert_allclose(diff[:, :3], 0.0, atol=1e-12)


def test_delay_serves_the_sample_of_d_ticks_earlier() -> None:
    a, b, _ = _lockstep([Fault(kind="delay", sensor="encoders", value=0.003, at=0.01)])
    qa, qb = _q(a), _q(b)
    np.testing.assert_array_equal(qb[:10], qa[:10])
    np.testing.assert_array_equal(qb[10:], qa[7:-3])
    np.testing.assert_array_equal(_w(b), _w(a))  # the force sensor is not delayed


def test_dropout_holds_the_last_value_and_flags_the_tick() -> None:
    a, b, _ = _lockstep(
        [Fault(kind="dropout", sensor="ft", robot="endobot_2", at=0.005, duration=0.004)]
    )
    wa, wb = _w(a, "endobot_2"), _w(b, "endobot_2")
    flags = [m.robots["endobot_2"].fault for m in b]
    assert flags == [5 <= k < 9 for k in range(N + 1)]
    np.testing.assert_array_equal(wb[5:9], np.repeat(wa[4:5], 4, axis=0))
    np.testing.assert_array_equal(wb[9:], wa[9:])
    assert not any(m.robots["endobot_1"].fault for m in b)


def test_noise_has_the_declared_standard_deviation_and_the_seed_fixes_it() -> None:
    fault = Fault(kind="noise", sensor="ft", value=0.2)
    a, b, _ = _lockstep([fault], ticks=3000, seed=7)
    noise = (_w(b) - _w(a))[:, :3]
    assert noise.std() == pytest.approx(0.2, rel=0.05)
    assert abs(noise.mean()) < 0.02
    _, b2, _ = _lockstep([fault], ticks=50, seed=7)
    _, b3, _ = _lockstep([fault], ticks=50, seed=8)
    np.testing.assert_array_equal(_w(b2), _w(b)[:51])
    assert np.abs(_w(b3) - _w(b)[:51]).max() > 1e-3


def test_joint_weak_scales_the_joints_torque_only() -> None:
    spy = Spy()
    _lockstep([Fault(kind="joint-weak", robot="endobot_2", joint="roll", value=0.25)], inner=spy)
    for k, applied in enumerate(spy.applied):
        want = _tau(k).robots
        np.testing.assert_allclose(applied["endobot_2"][2], 0.25 * want["endobot_2"].tau[2])
        np.testing.assert_array_equal(
            applied["endobot_2"][[0, 1, 3]], want["endobot_2"].tau[[0, 1, 3]]
        )
        np.testing.assert_array_equal(applied["endobot_1"], want["endobot_1"].tau)


def test_joint_lock_brakes_the_joint_where_it_locked() -> None:
    lock = Fault(kind="joint-lock", robot="endobot_1", joint="yaw", at=0.05, duration=0.3)
    push = Command({"endobot_1": RobotCommand.torque([0.5, 0.0, 0.0, 0.0])})
    runs = []
    for be in (IdealBackend(), FaultyBackend(IdealBackend(), [lock])):
        qs = [be.reset(SCENE, 0).robots["endobot_1"].q[0]]
        for _ in range(400):
            be.apply(push)
            be.step()
            qs.append(be.observe().robots["endobot_1"].q[0])
        runs.append(np.array(qs))
    qa, qb = runs
    moved = abs(qa[350] - qa[50])
    assert moved > 0.05  # the torque turns the free joint a lot
    assert np.abs(qb[50:350] - qb[50]).max() < 0.02 * moved  # the locked one stays
    assert abs(qb[400] - qb[350]) > 1e-3  # released at its end: it moves again


def test_nan_blow_up_makes_every_measurement_nan_from_its_onset() -> None:
    _, b, _ = _lockstep([Fault(kind="blow-up", at=0.02)])
    assert np.all(np.isfinite(_q(b)[:20]))
    for robot in ("endobot_1", "endobot_2"):
        assert np.all(np.isnan(_q(b, robot)[20:])) and np.all(np.isnan(_w(b, robot)[20:]))


def test_energy_blow_up_pushes_with_an_exploding_force() -> None:
    spy = Spy()
    _lockstep(
        [Fault(kind="blow-up", mode="energy", robot="endobot_1", at=0.01)], ticks=400, inner=spy
    )
    pushes = [(t, f[2]) for t, r, f, _ in spy.pushes if r == "endobot_1"]
    assert pushes[0][0] == 10 and not any(r == "endobot_2" for _, r, _, _ in spy.pushes)
    mags = np.array([m for _, m in pushes])
    assert np.all(np.diff(mags) >= 0) and mags[-1] == pytest.approx(0.5 * ENERGY_CAP_N)
    assert mags[50] / mags[0] == pytest.approx(np.exp(0.05 / 0.05), rel=1e-9)


def test_grasp_slip_and_snag_call_the_backend_hooks_once_at_their_onset() -> None:
    spy = Spy()
    faults = [
        Fault(kind="grasp-slip", robot="endobot_2", at=0.012),
        Fault(kind="snag", value=2.5, at=0.02, duration=0.1),
    ]
    _lockstep(faults, inner=spy)
    assert spy.slips == [(12, "endobot_2")]
    assert spy.snags == [(20, 2.5, 0.1)]


def test_a_backend_without_the_hooks_is_refused() -> None:
    with pytest.raises(FaultNotSupported, match="ideal"):
        FaultyBackend(IdealBackend(), [Fault(kind="snag", value=1.0)])
    with pytest.raises(FaultNotSupported, match="inject_grasp_slip"):
        FaultyBackend(IdealBackend(), [Fault(kind="grasp-slip")], backend_name="pybullet-surgical")


def test_state_trigger_waits_for_the_state_and_records_start_and_end() -> None:
    state = {"now": None}
    messages: list[tuple[int, dict[str, Any]]] = []
    fault = Fault(kind="bias", sensor="ft", value=1.0, when="tighten", at=0.002, duration=0.005)
    be = FaultyBackend(IdealBackend(), [fault, Fault(kind="noise", sensor="ft", value=0.01)])
    be.reset(SCENE, 0)  # the noise starts at reset, before any sink: kept
    be.attach(lambda t, m: messages.append((t, m)), lambda: state["now"])
    first = [(t, m["kind"], m["phase"]) for t, m in messages]
    assert first == [(0, "noise", "start")]
    for k in range(30):
        state["now"] = "simple-knot.tighten" if k >= 10 else "simple-knot.grab"
        be.apply(_tau(k))
        be.step()
        be.observe()
    bias = [(t, m["phase"], m["trigger"]) for t, m in messages if m["kind"] == "bias"]
    # first seen by the measurement of tick 11, then 2 ms later, for 5 ms
    assert bias == [(13_000_000, "start", "when tighten"), (18_000_000, "end", "when tighten")]


def test_random_rate_onsets_are_poisson_and_fixed_by_the_seed() -> None:
    from suture_engine.faults.schedule import FaultSchedule

    fault = Fault(kind="dropout", sensor="ft", rate=2.0, duration=0.001)

    def onsets(seed: int) -> list[int]:
        sched = FaultSchedule([fault], seed, 1e-3)
        return [o.start for k in range(100_000) for o in sched.update(k)[0]]

    first = onsets(3)
    assert first == onsets(3) and first != onsets(4)
    assert abs(len(first) - 200) < 4 * np.sqrt(200)  # 100 s at 2/s
    gaps = np.diff(first) * 1e-3
    assert gaps.mean() == pytest.approx(0.5, rel=0.2)
