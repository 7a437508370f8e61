"""``suture identify``: run the identification experiments and print a Table 3.4-style table.

The table has, per joint, each identified parameter beside the value the
simulated robot was built with and the relative error, then the regressor's
condition number (3.54).
"""

from __future__ import annotations

import math

from suture_engine.robot.identification_experiment import IdentificationReport

__all__ = ["identify_command", "report_table"]

_JOINT_NAMES = ("yaw", "pitch", "roll", "insertion")
_UNITS = (
    ("I [kg m^2]", "ml [kg m]", "Fc [N m]", "Fv [N m s]"),
    ("I [kg m^2]", "ml [kg m]", "Fc [N m]", "Fv [N m s]"),
    ("I [kg m^2]", "ml [kg m]", "Fc [N m]", "Fv [N m s]"),
    ("m [kg]", "m (weight) [kg]", "Fc [N]", "Fv [N s/m]"),
)


def _pct(est: float, true: float) -> str:
    if math.isnan(est) or math.isnan(true) or true == 0.0:
        return "-"
    return f"{100.0 * (est - true) / true:+.1f}%"


def _num(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:.4g}"


def report_table(report: IdentificationReport) -> object:
    """A rich table of the report (Table 3.4 layout, with truth and error columns)."""
    from rich.markup import escape
    from rich.table import Table

    parts = []
    if report.quantised:
        parts.append("quantised encoders")
    if report.encoder_noise:
        parts.append(f"encoder noise {report.encoder_noise:g}")
    noise = ", ".join(parts) or "clean encoders"
    table = Table(
        title=f"EndoBot {report.robot}: {report.signal} excitation, {report.method} model, {noise}"
    )
    for col in ("joint", "parameter", "estimate", "simulated", "error"):
        table.add_column(col, justify="right" if col != "parameter" else "left")
    for res in report.joints:
        units = _UNITS[res.joint]
        for k in range(4):
            est, true = res.estimate[k], res.truth[k]
            if math.isnan(true):
                continue
            table.add_row(
                f"{report.robot}{res.joint + 1} {_JOINT_NAMES[res.joint]}" if k == 0 else "",
                escape(units[k]),
                _num(est),
                _num(true),
                _pct(est, true),
            )
        table.add_row("", "cond(phi) (3.54)", f"{res.estimate.condition:.0f}", "", "")
        v = res.validation
        table.add_row("", "residual / torque RMS", f"{v.relative_residual:.3f}", "", "")
        table.add_row(
            "", "r(residual, input) (3.77)", f"{v.input_correlation:+.3f}", "", "", end_section=True
        )
    return table


def identify_command(
    *,
    robot: str = "E1",
    signal: str = "schroeder",
    method: str = "differential",
    duration: float = 10.0,
    encoder_noise: float = 0.0,
    quantised: bool = False,
    seed: int = 0,
    joints: list[int] | None = None,
) -> int:
    """Run ``suture identify``; returns the exit code.

    Args:
        robot: "E1" or "E2".
        signal: excitation kind (schroeder, multisine, chirp, prbs).
        method: "differential" or "energy".
        duration: excitation length per joint [s].
        encoder_noise: encoder noise standard deviation [rad and m].
        quantised: quantise the encoders.
        seed: noise seed.
        joints: joints to identify, 1-4 (default all).

    Returns:
        0 on success, 1 when identification failed, 2 on bad options.
    """
    from rich.console import Console

    from suture_engine.errors import SutureError
    from suture_engine.robot.excitation import ExcitationKind
    from suture_engine.robot.identification_experiment import identify_robot
    from suture_engine.robot.params import E1, E2

    err = Console(stderr=True)
    params = {"E1": E1, "E2": E2}.get(robot.upper())
    kinds = [k.value for k in ExcitationKind]
    chosen = joints or [1, 2, 3, 4]
    problems = []
    if params is None:
        problems.append(f"unknown robot {robot!r}; choose E1 or E2")
    if signal not in kinds:
        problems.append(f"unknown signal {signal!r}; choose one of {', '.join(kinds)}")
    if method not in ("differential", "energy"):
        problems.append(f"unknown method {method!r}; choose differential or energy")
    if not (duration >= 2.0 and math.isfinite(duration)):
        problems.append(f"duration {duration} s is too short; use at least 2 s")
    if not (encoder_noise >= 0.0 and math.isfinite(encoder_noise)):
        problems.append(f"encoder noise {encoder_noise} must be >= 0")
    if any(j not in (1, 2, 3, 4) for j in chosen):
        problems.append(f"joints {chosen} must be in 1-4")
    if problems or params is None:
        for msg in problems:
            err.print(f"error: {msg}")
        return 2
    try:
        report = identify_robot(
            params,
            signal=signal,
            duration=duration,
            encoder_noise=encoder_noise,
            quantised=quantised,
            seed=seed,
            method=method,
            joints=tuple(sorted({j - 1 for j in chosen})),
        )
    except SutureError as exc:
        err.print(f"error: {exc.code}: {exc.message}")
        return 1
    Console().print(report_table(report))
    return 0
