"""Per-call cost of the chapter 5 controller updates, in µs (median of repeats).

The 1 kHz budget target of the model + control path is FK + Jacobian + gravity
+ one controller update <= 20 µs median together; the last rows measure that
chain in one call, with the PD (which evaluates gravity itself) and with the
LQR (which also evaluates M and C for feedback linearisation).

    python benchmarks/controller_call_cost.py
"""

from __future__ import annotations

import statistics
import timeit
from collections.abc import Callable

import numpy as np

from suture_engine.control.filters import NumericalDifferentiator, WashoutFilter
from suture_engine.control.gravity import GravityCompensation
from suture_engine.control.kalman import KalmanVelocityObserver, LQGController
from suture_engine.control.lqr import FeedbackLinearizingLQR
from suture_engine.control.model import endobot_control_model
from suture_engine.control.pd import PDController, gains_at_workspace_centre
from suture_engine.robot import endobot

REPEATS = 31
NUMBER = 2000


def per_call_us(fn: Callable[[], object]) -> float:
    """Median per-call time [µs] over REPEATS batches of NUMBER calls."""
    return statistics.median(timeit.repeat(fn, number=NUMBER, repeat=REPEATS)) / NUMBER * 1e6


def main() -> None:
    """Print the table."""
    dt = 1e-3
    q = np.array([0.2, -0.3, 0.4, 0.12])
    qd = np.array([0.5, -0.2, 0.3, 0.01])
    qr = q + 0.01
    vr = qd * 0.9
    ar = np.array([0.1, 0.2, -0.1, 0.0])
    jac = np.zeros((4, 4))
    model = endobot_control_model()
    pd = PDController(gains_at_workspace_centre(7.0), model)
    grav = GravityCompensation(model)
    lqr = FeedbackLinearizingLQR(model, dt)
    lqg = LQGController(model, dt)
    kal = KalmanVelocityObserver(4, dt)
    wo = WashoutFilter(100.0, dt)
    nd = NumericalDifferentiator(dt)

    def chain_pd() -> None:
        endobot.forward_kinematics(q)
        endobot.jacobian(q, out=jac)
        pd.update(q, qd, qr, vr)

    def chain_lqr() -> None:
        endobot.forward_kinematics(q)
        endobot.jacobian(q, out=jac)
        lqr.update(q, qd, qr, vr, ar)

    rows = {
        "washout filter": lambda: wo.update(q),
        "numerical differentiator": lambda: nd.update(q),
        "gravity compensation (5.1)": lambda: grav.update(q),
        "PD + G + Coulomb (5.10)": lambda: pd.update(q, qd, qr, vr),
        "FL + LQR + integral (5.21)": lambda: lqr.update(q, qd, qr, vr, ar),
        "Kalman observer (5.53)": lambda: kal.update(q, ar),
        "LQG (observer + FL-LQR)": lambda: lqg.update(q, qr, vr, ar),
        "FK + J + (G in) PD": chain_pd,
        "FK + J + (G, M, C in) LQR": chain_lqr,
    }
    print(f"{'call':<30}{'median µs/call':>16}")
    for name, fn in rows.items():
        print(f"{name:<30}{per_call_us(fn):>16.2f}")


if __name__ == "__main__":
    main()
