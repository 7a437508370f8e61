"""A simulated calibration error of the robots' bases.

A real bench knows where each robot's base (its remote centre of motion) stands only as
well as it was calibrated. In simulation that error can be modelled two ways:

- the robot is built off the base the scene declares and the skills plan from the
  declared one (a *placement* error: the backend's ``base_error`` option), or
- the robot is built where the scene declares it and the skills plan from a base that is
  off (a *calibration* error, this module: the interpreter's ``calibration_error``).

Without a ``register`` step the two move the tool tips alike. With one they differ: a
register step measures the base, and after it a calibration error is gone, while a
placement error leaves the instruments coming in at their moved ports.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

from suture_engine.errors import InvalidValue, SutureError

__all__ = ["CalibrationSpecError", "calibration_offsets", "parse_calibration_spec"]


class CalibrationSpecError(SutureError):
    """A ``--calibration-error`` value that is not ``ROBOT=X,Y,Z`` (millimetres).

    Attributes:
        spec: the value given.
        expected: what was expected, in words.
    """

    code = "bad-calibration-error"

    def __init__(self, spec: str, expected: str) -> None:
        super().__init__(f"--calibration-error {spec!r}: expected {expected}")
        self.spec = spec
        self.expected = expected


def parse_calibration_spec(spec: str) -> tuple[str, tuple[float, float, float]]:
    """``ROBOT=X,Y,Z`` (the believed base minus the actual one, in millimetres) as the
    robot's name and the vector in metres.

    Raises:
        CalibrationSpecError: not of that form, or a component that is not a finite
            number.
    """
    name, sep, rest = spec.partition("=")
    parts = [p.strip() for p in rest.split(",")]
    if not sep or not name.strip() or len(parts) != 3:
        raise CalibrationSpecError(spec, "ROBOT=X,Y,Z in mm, e.g. endobot_2=1,0,-0.5")
    try:
        mm = [float(p) for p in parts]
    except ValueError:
        raise CalibrationSpecError(spec, "three numbers in mm after the '='") from None
    if not all(math.isfinite(v) for v in mm):
        raise CalibrationSpecError(spec, "finite numbers in mm")
    return name.strip(), (mm[0] * 1e-3, mm[1] * 1e-3, mm[2] * 1e-3)


def calibration_offsets(
    errors: Mapping[str, Sequence[float]] | None, scene: Any
) -> dict[str, tuple[float, float, float]]:
    """Each robot's believed base minus its actual one [m], checked against the scene.

    Args:
        errors: robot name -> (x, y, z) [m] in the world frame, or None (none).
        scene: the scene model whose ``robots`` name the robots (None: no robots).

    Returns:
        robot name -> the offset as a tuple of three floats [m].

    Raises:
        InvalidValue: a robot the scene does not have, or a vector that is not three
            finite numbers.
    """
    if not errors:
        return {}
    robots = sorted(getattr(scene, "robots", None) or {})
    out: dict[str, tuple[float, float, float]] = {}
    for name, vector in errors.items():
        if name not in robots:
            raise InvalidValue(
                "calibration_error", name, f"a robot of the scene ({', '.join(robots) or 'none'})"
            )
        try:  # a list, a tuple or an array; not a string, not a single number
            values = () if isinstance(vector, (str, bytes)) else tuple(vector)
        except TypeError:
            values = ()
        if len(values) != 3 or not all(
            isinstance(v, numbers.Real) and math.isfinite(v) for v in values
        ):
            raise InvalidValue(f"calibration_error.{name}", vector, "three finite numbers [m]")
        out[str(name)] = (float(values[0]), float(values[1]), float(values[2]))
    return out
