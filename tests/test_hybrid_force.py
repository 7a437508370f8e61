"""Explicit PI force control with active damping (7.22), its reference and the hybrid law.

The stability oracle is the linear plant ``m x'' + b x' + k x = u`` with ``f_m = k x``
(7.23-7.24), discretised exactly (zero-order hold, matrix exponential) by scipy and
closed with the controller under test at 1 kHz: it must be stable just below the
Routh bound of ``integral_gain_bound`` (7.29, 7.33) and unstable just above it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import cont2discrete

from suture_engine.control.force import integral_gain_bound
from suture_engine.control.hybrid_force import (
    ExplicitForceController,
    ForceGainsError,
    HybridForcePositionController,
    ModifiedForceReference,
    selection_matrices,
)
from suture_engine.robot import endobot

DT = 1e-3


def _plant(m: float, b: float, k: float) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([[0.0, 1.0], [-k / m, -b / m]])
    bm = np.array([[0.0], [1.0 / m]])
    ad, bd, *_ = cont2discrete((a, bm, np.eye(2), np.zeros((2, 1))), DT, method="zoh")
    return np.asarray(ad), np.asarray(bd).ravel()


def _closed_loop(
    ctrl: ExplicitForceController,
    m: float,
    b: float,
    k: float,
    reference: float | np.ndarray,
    seconds: float,
    clip: float = math.inf,
    delay_ticks: int = 0,
) -> np.ndarray:
    """Simulate; return the measured force per sample (the force reaches the
    controller ``delay_ticks`` samples late, (7.34))."""
    ad, bd = _plant(m, b, k)
    n = round(seconds / DT)
    refs = np.broadcast_to(np.asarray(reference, dtype=float), (n,))
    x = np.zeros(2)
    out = np.empty(n)
    for i in range(n):
        f = k * x[0]
        out[i] = f
        f_meas = out[i - delay_ticks] if i >= delay_ticks else 0.0
        u = min(max(ctrl.update(float(refs[i]), f_meas, x[1]), -clip), clip)
        x = ad @ x + bd * u
    return out


@pytest.mark.parametrize(("kp", "kv"), [(1.0, 0.0), (0.5, 3.0)])
def test_stable_just_below_and_unstable_just_above_the_routh_bound(kp: float, kv: float) -> None:
    m, b, k = 1.0, 1.0, 10.0
    bound = integral_gain_bound(m, b, k, kp, kv)
    envelopes = {}
    for factor in (0.9, 1.1):
        ctrl = ExplicitForceController(kp, factor * bound, kv, DT)
        f = _closed_loop(ctrl, m, b, k, 1.0, 120.0)
        err = np.abs(f - 1.0)
        n = len(err)
        envelopes[factor] = (err[n // 4 : n // 2].max(), err[3 * n // 4 :].max())
    early, late = envelopes[0.9]
    assert late < 0.5 * early  # decaying
    early, late = envelopes[1.1]
    assert late > 2.0 * early  # growing


def test_delayed_measurement_bound() -> None:
    """With a 2 ms force delay, Kp = 10 (Fig. 7.18): stable at 0.9 and unstable at 1.1
    times the bound of (7.41); the delay-free bound would call both stable."""
    m, b, k, kp, delay = 1.0, 1.0, 10.0, 10.0, 2e-3
    bound = integral_gain_bound(m, b, k, kp, 0.0, delay)
    assert integral_gain_bound(m, b, k, kp) > 1.1 * bound
    envelopes = {}
    for factor in (0.9, 1.1):
        ctrl = ExplicitForceController(kp, factor * bound, 0.0, DT)
        f = _closed_loop(ctrl, m, b, k, 1.0, 120.0, delay_ticks=round(delay / DT))
        err = np.abs(f - 1.0)
        n = len(err)
        envelopes[factor] = (err[n // 4 : n // 2].max(), err[3 * n // 4 :].max())
    early, late = envelopes[0.9]
    assert late < 0.5 * early
    early, late = envelopes[1.1]
    assert late > 2.0 * early


def test_integral_action_removes_the_steady_state_error() -> None:
    ctrl = ExplicitForceController(0.3, 0.5, 2.0, DT)
    f = _closed_loop(ctrl, 1.0, 1.0, 10.0, 5.0, 60.0)
    assert f[-1] == pytest.approx(5.0, abs=1e-3)


def test_output_saturates_and_the_integral_does_not_wind_up() -> None:
    """Reference out of reach for 20 s, then reachable: the clamped integral leaves
    saturation at once; the same gains clipped outside the controller wind up."""
    m, b, k, limit = 1.0, 2.0, 10.0, 5.0
    refs = np.concatenate((np.full(20_000, 20.0), np.full(20_000, 2.0)))  # 20 N unreachable
    clamped = ExplicitForceController(0.2, 1.0, 1.0, DT, limit=limit)
    f_clamped = _closed_loop(clamped, m, b, k, refs, 40.0)
    windup = ExplicitForceController(0.2, 1.0, 1.0, DT)
    f_windup = _closed_loop(windup, m, b, k, refs, 40.0, clip=limit)
    assert f_clamped[19_999] == pytest.approx(limit, abs=1e-3)  # at rest f = k x = u_max
    assert clamped.integral < 50.0  # bounded (the unclamped one reached ~ 15 N * 20 s)

    def settle(f: np.ndarray) -> float:
        tail = np.abs(f[20_000:] - 2.0) > 0.2
        return float(np.nonzero(tail)[0].max() * DT) if tail.any() else 0.0

    assert settle(f_clamped) < 8.0
    assert settle(f_windup) > 2.0 * settle(f_clamped)


def test_saturated_output_is_exactly_the_limit() -> None:
    ctrl = ExplicitForceController(1.0, 0.0, 0.0, DT, limit=3.0)
    assert ctrl.update(10.0, 0.0, 0.0) == 3.0
    assert ctrl.saturated
    assert ctrl.update(-10.0, 0.0, 0.0) == -3.0
    assert ctrl.update(1.0, 0.0, 0.0) == pytest.approx(1.0)
    assert not ctrl.saturated


def test_active_damping_opposes_velocity() -> None:
    ctrl = ExplicitForceController(0.0, 0.0, 100.0, DT)
    assert ctrl.update(0.0, 0.0, 0.02) == pytest.approx(-2.0)


def test_modified_reference_shape() -> None:
    """Leads the measured force by the margin, never decreases, stops at the target,
    rises no faster than the rate limit."""
    ref = ModifiedForceReference(15.0, lead=5.0, dt=2e-3)
    measured = np.concatenate(
        (np.zeros(50), np.linspace(0.0, 12.0, 400), np.linspace(12.0, 4.0, 100), np.full(50, 20.0))
    )
    r = np.array([ref.update(float(f)) for f in measured])
    assert r[0] == pytest.approx(5.0)
    assert np.all(np.diff(r) >= 0.0)
    assert r.max() == pytest.approx(15.0)
    rising = slice(50, 450)
    np.testing.assert_allclose(r[rising], np.minimum(measured[rising] + 5.0, 15.0))
    assert np.all(r[450:550] == r[449])  # held while the measured force drops

    slow = ModifiedForceReference(15.0, lead=5.0, dt=2e-3, rate=10.0)
    rs = np.array([slow.update(float(f)) for f in measured])
    assert np.diff(rs).max() <= 10.0 * 2e-3 + 1e-12
    assert np.all(rs <= r + 1e-12)


def test_selection_matrices_split_the_task_space() -> None:
    sf, sm = selection_matrices((1.0, 2.0, -2.0))
    e = np.array([1.0, 2.0, -2.0]) / 3.0
    np.testing.assert_allclose(sf @ e, e)
    np.testing.assert_allclose(sm @ e, 0.0, atol=1e-15)
    np.testing.assert_allclose(sf + sm, np.eye(3))
    np.testing.assert_allclose(sf @ sm, 0.0, atol=1e-15)


def test_force_torques_do_the_virtual_work_of_the_force() -> None:
    """tau - G = J^T e u_f (7.15): checked by finite differences of the kinematics."""
    e = np.array([0.6, -0.48, 0.64])
    q = np.array([0.2, -0.3, 0.5, 0.1])
    tip = endobot.forward_kinematics(q).position
    ctrl = HybridForcePositionController(
        e, tip, ExplicitForceController(0.0, 0.0, 0.0, DT), kx=0.0, dx=0.0, kr=0.0, dr=0.0
    )
    cmd = ctrl.update(q, np.zeros(4), measured=0.0, reference=7.0)
    assert cmd.force == pytest.approx(0.0)  # Ki = Kp = 0: no force yet
    ctrl = HybridForcePositionController(
        e, tip, ExplicitForceController(1.0, 0.0, 0.0, DT), kx=0.0, dx=0.0, kr=0.0, dr=0.0
    )
    cmd = ctrl.update(q, np.zeros(4), measured=0.0, reference=7.0)
    tau = cmd.torque - endobot.gravity_vector(q)
    h = 1e-6
    for i in range(4):
        dq = np.zeros(4)
        dq[i] = h
        dx = (
            endobot.forward_kinematics(q + dq).position
            - endobot.forward_kinematics(q - dq).position
        )
        work = float(7.0 * e @ dx / (2 * h))
        assert tau[i] == pytest.approx(work, abs=1e-6)


def test_motion_part_pulls_back_onto_the_line_only_across_it() -> None:
    e = np.array([1.0, 0.0, 0.0])
    q = np.array([0.1, 0.2, 0.0, 0.1])
    tip = endobot.forward_kinematics(q).position
    off = np.array([0.003, -0.002, 0.001])  # line passes 'off' away from the tip
    ctrl = HybridForcePositionController(
        e, tip + off, ExplicitForceController(0.0, 0.0, 0.0, DT), kx=1000.0, dx=0.0
    )
    cmd = ctrl.update(q, np.zeros(4), 0.0, 0.0)
    assert cmd.line_error == pytest.approx(math.hypot(off[1], off[2]))
    jt = endobot.jacobian(q)[:3].T
    expected = jt @ (1000.0 * np.array([0.0, off[1], off[2]]))
    np.testing.assert_allclose(cmd.torque - endobot.gravity_vector(q), expected, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"kp": -1.0, "ki": 0.1, "kv": 0.0, "dt": DT}, "kp"),
        ({"kp": 0.0, "ki": math.nan, "kv": 0.0, "dt": DT}, "ki"),
        ({"kp": 0.0, "ki": 0.1, "kv": 0.0, "dt": 0.0}, "dt"),
        ({"kp": 0.0, "ki": 0.1, "kv": 0.0, "dt": DT, "limit": 0.0}, "limit"),
    ],
)
def test_bad_gains_are_typed_errors(kwargs: dict[str, float], name: str) -> None:
    with pytest.raises(ForceGainsError) as err:
        ExplicitForceController(**kwargs)
    assert err.value.name == name


def test_friction_compensation_adds_the_identified_friction() -> None:
    """Coulomb (smoothed sign) and, optionally, viscous friction of Table 3.3 are added."""
    prm = endobot.E1
    fr = [j.friction for j in prm.joints]
    q = np.array([0.1, 0.2, 0.0, 0.1])
    qd = np.array([0.5, -0.5, 0.0, 1e-4])
    tip = endobot.forward_kinematics(q).position
    base = HybridForcePositionController(
        (1.0, 0.0, 0.0), tip, ExplicitForceController(0.0, 0.0, 0.0, DT), kx=0.0, dx=0.0
    )
    tau0 = base.update(q, qd, 0.0, 0.0).torque
    for viscous in (False, True):
        comp = HybridForcePositionController(
            (1.0, 0.0, 0.0),
            tip,
            ExplicitForceController(0.0, 0.0, 0.0, DT),
            kx=0.0,
            dx=0.0,
            friction=fr,
            viscous=viscous,
            smoothing=0.01,
        )
        extra = comp.update(q, qd, 0.0, 0.0).torque - tau0
        assert extra[0] == pytest.approx(fr[0].coulomb + viscous * fr[0].viscous * 0.5, rel=1e-6)
        assert extra[1] == pytest.approx(-fr[1].coulomb - viscous * fr[1].viscous * 0.5, rel=1e-6)
        assert extra[2] == 0.0
        smooth = fr[3].coulomb * math.tanh(0.01) + viscous * fr[3].viscous * 1e-4
        assert extra[3] == pytest.approx(smooth, rel=1e-6)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_stiction_compensation_turns_joints_at_rest_the_way_the_tip_must_go(sign: float) -> None:
    """At rest with the tension 0.5 N too low (sign +1: pull along e) or too high (-1),
    outside a 0.1 N band, each joint's static friction is added in the sense that moves
    the tip along ``sign * e``; the sense is checked on joint rates from the kinematics'
    finite differences. Inside the band nothing is added."""
    prm = endobot.E1
    fr = [j.friction for j in prm.joints]
    q = np.array([0.15, -0.2, 0.3, 0.12])
    e = np.array([0.3, -0.8, 0.2])
    e /= np.linalg.norm(e)
    tip = endobot.forward_kinematics(q).position

    def torque(measured: float, band: float | None) -> np.ndarray:
        ctrl = HybridForcePositionController(
            e, tip, ExplicitForceController(0.0, 0.0, 0.0, DT), prm, kx=0.0, dx=0.0,
            friction=fr, stiction_band=band,
        )  # fmt: skip
        return ctrl.update(q, np.zeros(4), measured, 1.0).torque

    extra = torque(1.0 - 0.5 * sign, 0.1) - torque(1.0 - 0.5 * sign, None)
    h = 1e-6
    jac = np.column_stack(
        [(endobot.forward_kinematics(q + h * np.eye(4)[i]).position - tip) / h for i in (0, 1, 3)]
    )
    rates = np.linalg.solve(jac, sign * e)
    for k, joint in enumerate((0, 1, 3)):
        expected = fr[joint].static * math.tanh(rates[k] / (0.1 * np.abs(rates).max()))
        assert extra[joint] == pytest.approx(expected, rel=1e-3, abs=1e-9)
        assert np.sign(extra[joint]) == np.sign(rates[k])
    assert extra[2] == 0.0
    inside = torque(1.05, 0.1) - torque(1.05, None)
    assert np.all(inside == 0.0)
