"""The tension experiments of 7.5 (Tables 7.3-7.5): the thesis' ordering, from simulated runs.

Each assertion compares peaks of simulated runs that also reach the desired tension,
so a lower peak cannot come from a run that never got there.
"""

from __future__ import annotations

import pytest

from suture_engine.control.tension_experiment import (
    SutureSpring,
    TensionCase,
    run_tension_experiment,
    thesis_cases,
    windup_force,
)

pytest.importorskip("pybullet")

TARGET = 15.0


def _by_label() -> dict[str, TensionCase]:
    return {c.label: c for c in thesis_cases()}


def test_active_damping_lowers_the_contact_spike() -> None:
    """Fast variant: integral control alone against Kv = 1000, 6 s each."""
    cases = _by_label()
    bare = run_tension_experiment(cases["Ki=0.5, Kv=0"], duration=6.0)
    damped = run_tension_experiment(cases["Ki=0.5, Kv=1000"], duration=6.0)
    assert damped.final_error < 1.0  # within 1 N of 15 N by the end of the run
    assert bare.max_force > TARGET + 3.0  # the contact spike
    assert damped.max_force < bare.max_force - 3.0
    assert damped.max_true < bare.max_true  # the simulated suture agrees with the estimate
    # the base-sensor estimate in closed loop, against the simulated suture's tension
    assert abs(damped.measured[-1] - damped.true_tension[-1]) < 0.2


@pytest.mark.slow
def test_thesis_ordering_over_full_runs() -> None:
    """30 s runs as Figs. 7.21-7.29: Kv lowers the peak, the ramped reference lowers it
    further below the same Kv = 2000 without the ramp, and every run reaches 15 N."""
    cases = _by_label()
    labels = (
        "Ki=0.5, Kv=0",
        "Ki=0.5, Kv=1000",
        "Ki=0.5, Kv=2000",
        "Kp=0.2, Ki=0.3, Kv=2000, ramped",
    )
    runs = {label: run_tension_experiment(cases[label], duration=30.0) for label in labels}
    peaks = {label: run.max_force for label, run in runs.items()}
    for label in labels[1:]:
        assert runs[label].final_error < 0.2, label
    bare, kv1, kv2, ramp = (peaks[label] for label in labels)
    assert kv1 < bare and kv2 < bare
    assert ramp < kv2
    assert ramp <= TARGET * 1.01  # the modified reference does not overshoot


def test_large_damping_peak_is_the_integrator_windup_over_the_slack() -> None:
    """Why Kv = 2000 peaks above Kv = 1000 here (thesis: below): while the suture is slack,
    the damping holds the tip to a creep and the integral winds up to sqrt(2 Ki F Kv s)
    (``windup_force``, derived independently of the controller code) by the time the slack
    is taken up; the taut suture stops the tip and the tension rises to that integral.
    Predicted 17.3 N for Ki = 0.5, Kv = 2000, 15 N, 10 mm; 12.2 N (< 15 N: no overshoot)
    for Kv = 1000."""
    case = _by_label()["Ki=0.5, Kv=2000"]
    spring = SutureSpring()
    run = run_tension_experiment(case, duration=4.0, spring=spring)
    predicted = windup_force(case.ki, case.kv, TARGET, spring.slack)
    assert predicted > TARGET
    assert run.max_force > TARGET + 1.0  # it does overshoot ...
    assert run.max_force == pytest.approx(predicted, rel=0.1)  # ... by the wound-up integral
    assert run.max_true == pytest.approx(run.max_force, rel=0.02)  # not a sensing artefact
    assert windup_force(case.ki, 1000.0, TARGET, spring.slack) < TARGET


@pytest.mark.slow
def test_less_slack_removes_the_large_damping_overshoot() -> None:
    """With 2 mm of slack the predicted windup (7.7 N) stays below 15 N: no overshoot at
    Kv = 2000, and the peak is below the 10 mm run's."""
    case = _by_label()["Ki=0.5, Kv=2000"]
    short = SutureSpring(slack=0.002)
    assert windup_force(case.ki, case.kv, TARGET, short.slack) < TARGET
    run = run_tension_experiment(case, duration=15.0, spring=short)
    assert run.final_error < 0.5
    assert run.max_force < TARGET + 0.3
    long = run_tension_experiment(case, duration=6.0)
    assert run.max_force < long.max_force - 1.0
