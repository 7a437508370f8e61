"""Faults as data: one injected fault of a run (the scene's ``faults:`` list, ``--fault``).

A :class:`Fault` says *what* goes wrong (``kind`` and its target: a sensor, a
joint, a robot's grasp, the suture, the physics), *how much* (``value``, in the
unit of the kind) and *when* (the trigger):

- timed: ``at`` [s] after the start (or after ``when``), for ``duration`` [s];
- tied to a state: ``when: <state>``, the first time that state is entered
  (``at`` is then a delay after the entry);
- random with a seed: ``rate`` [1/s] (Poisson onsets, each lasting ``duration``)
  or ``probability`` (one onset, with that probability, at a uniform time in
  ``[at, at + within]``). The stream is ``seed`` (default: the run's seed) and
  the fault's index in the list, so the same seed gives the same faults.

Kinds, with the unit of ``value``:

================ =============================================================
``noise``        sensor noise, standard deviation: ``ft`` [N] (forces),
                 ``encoders`` [rad] (rotary joints) or [m] (insertion)
``bias``         sensor offset, same units; the ``ft`` bias is along ``axis``
``delay``        sensor delay [s] (thesis 7.4.2: 2 ms)
``dropout``      the sensor holds its last value and flags the tick (no value)
``grasp-slip``   the jaw of ``robot`` loses the suture (no value; backend hook)
``snag``         extra suture-tissue friction [N] for ``duration`` (backend hook)
``joint-lock``   ``joint`` of ``robot`` brakes where it is (no value)
``joint-weak``   ``joint``'s torque scaled by ``value`` in [0, 1) [-]
``blow-up``      ``mode: nan`` (the physics state reads NaN from then on) or
                 ``mode: energy`` (an exploding force at the tool tip)
================ =============================================================
"""

from __future__ import annotations

import math
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from suture_engine.language.units import (
    Duration,
    Rate,
    UnitError,
    dimension_name,
    parse_quantity,
)

__all__ = [
    "EVENT_KINDS",
    "FAULT_KINDS",
    "JOINTS",
    "JOINT_KINDS",
    "SENSOR_KINDS",
    "Fault",
    "FaultKind",
    "Joint",
    "Rate",
    "Sensor",
]

FaultKind = Literal[
    "noise",
    "bias",
    "delay",
    "dropout",
    "grasp-slip",
    "snag",
    "joint-lock",
    "joint-weak",
    "blow-up",
]
FAULT_KINDS: tuple[str, ...] = get_args(FaultKind)
"""Every fault kind."""
SENSOR_KINDS = frozenset({"noise", "bias", "delay", "dropout"})
"""Kinds that change a measurement (``sensor`` required)."""
JOINT_KINDS = frozenset({"joint-lock", "joint-weak"})
"""Kinds that change a joint's command (``joint`` required)."""
EVENT_KINDS = frozenset({"grasp-slip", "snag"})
"""Kinds that happen once at their onset, through a backend hook."""

Sensor = Literal["ft", "encoders"]
Joint = Literal["yaw", "pitch", "roll", "insertion"]
JOINTS: tuple[str, ...] = get_args(Joint)
"""Joint names, in the order of q (q1 yaw .. q4 insertion)."""


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


_NO_VALUE = frozenset({"dropout", "grasp-slip", "joint-lock", "blow-up"})
_MAX_SENSOR_DELAY_S = 1.0


def _value_unit(kind: str, sensor: str | None, joint: str | None) -> str | None:
    """The unit ``value`` must have for this kind (None: any of several, decided later)."""
    if kind in ("noise", "bias"):
        if sensor == "ft":
            return "N"
        if joint == "insertion":
            return "m"
        if joint is not None:
            return "rad"
        return None  # encoders without a joint: rad (rotary joints) or m (insertion)
    if kind == "delay":
        return "s"
    if kind == "snag":
        return "N"
    if kind == "joint-weak":
        return ""
    return None


def _unit_error(expected: str, found: str) -> Exception:
    from pydantic_core import PydanticCustomError

    return PydanticCustomError(
        "unit_mismatch",
        "expected {expected}, found {found}",
        {"expected": expected, "found": found},
    )


def _check_range(kind: str, value: float) -> None:
    if kind == "noise" and value <= 0.0:
        raise ValueError(f"the noise's standard deviation must be > 0, found {value:g}")
    if kind == "delay" and not 0.0 < value <= _MAX_SENSOR_DELAY_S:
        raise ValueError(f"expected 0 < delay <= 1 s, found {value:g} s")
    if kind == "snag" and value <= 0.0:
        raise ValueError(f"the extra friction must be > 0 N, found {value:g} N")
    if kind == "joint-weak" and not 0.0 <= value < 1.0:
        raise ValueError(f"expected a torque scale in [0, 1), found {value:g}")


class Fault(BaseModel):
    """One fault to inject (see the module docstring for kinds, units and triggers)."""

    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)

    kind: FaultKind
    """What goes wrong: noise, bias, delay, dropout, grasp-slip, snag, joint-lock,
    joint-weak or blow-up."""
    sensor: Sensor | None = None
    """For noise, bias, delay and dropout: ``ft`` (base force/torque sensor) or ``encoders``."""
    robot: str | None = None
    """The robot (a scene robot name); empty: every robot."""
    joint: Joint | None = None
    """For joint-lock and joint-weak (required), and encoder noise or bias (optional):
    yaw, pitch, roll or insertion."""
    axis: Literal["x", "y", "z"] = "z"
    """For an ``ft`` bias: the force axis of the sensor frame it acts along."""
    mode: Literal["nan", "energy"] = "nan"
    """For blow-up: NaN in the physics state, or an exploding force (energy)."""
    value: float | None = None
    """The magnitude, in the kind's unit: noise std / bias [N] (ft) or [rad] / [m]
    (encoders), delay [s], snag extra friction [N], joint-weak torque scale [-]."""
    at: Duration | None = Field(default=None, ge=0.0)
    """Onset [s] after the start, or after entering ``when``; default 0."""
    duration: Duration | None = Field(default=None, gt=0.0)
    """How long it lasts [s]; empty: to the end of the run (snag: 200 ms; random
    onsets: 10 ms each)."""
    when: str | None = None
    """Start when this state is first entered (``at`` is then a delay after the entry)."""
    rate: Rate | None = Field(default=None, gt=0.0)
    """Random onsets at this mean rate [1/s] (a Poisson process)."""
    probability: float | None = Field(default=None, ge=0.0, le=1.0)
    """Random: the fault happens once with this probability, in ``[at, at + within]``."""
    within: Duration = Field(default=10.0, gt=0.0)
    """The window of a ``probability`` fault [s]."""
    seed: int | None = None
    """The random stream's seed (default: the run's seed)."""

    @model_validator(mode="before")
    @classmethod
    def _encoder_length_means_insertion(cls, data: Any) -> Any:
        """An encoder noise or bias written as a length, with no joint, is the insertion's."""
        if (
            isinstance(data, dict)
            and data.get("sensor") == "encoders"
            and data.get("kind") in ("noise", "bias")
            and data.get("joint") is None
            and isinstance(data.get("value"), str)
            and not _is_number(data["value"])
        ):
            try:
                q = parse_quantity(data["value"])
            except UnitError:
                return data  # reported by the value's own check
            if dimension_name(q.dim) == "length":
                return {**data, "joint": "insertion"}
        return data

    @field_validator("value", mode="before")
    @classmethod
    def _value_in_unit(cls, v: Any, info: ValidationInfo) -> Any:
        kind = info.data.get("kind")
        if v is None or kind is None:
            return v
        if kind in _NO_VALUE:
            raise ValueError(f"a {kind} fault takes no value")
        if isinstance(v, bool):
            raise ValueError("expected a number or a quantity")
        if isinstance(v, str) and _is_number(v):
            v = float(v)
        if isinstance(v, int | float):
            value = float(v)
        elif isinstance(v, str):
            try:
                q = parse_quantity(v)
            except UnitError as exc:
                raise ValueError(exc.message) from None
            unit = _value_unit(kind, info.data.get("sensor"), info.data.get("joint"))
            found = dimension_name(q.dim)
            if unit is None:  # encoder noise/bias without a joint
                if found not in ("angle", "length"):
                    raise _unit_error("an angle (rotary joints) or a length (insertion)", found)
            else:
                from suture_engine.language.units import parse_unit

                want = parse_unit(unit)[1] if unit else (0, 0, 0, 0)
                if q.dim != want:
                    raise _unit_error(f"{dimension_name(want)} ({unit or 'no unit'})", found)
            value = q.value
        else:
            raise ValueError("expected a number or a quantity")
        if not math.isfinite(value):
            raise ValueError("expected a finite value")
        _check_range(kind, value)
        return value

    @model_validator(mode="after")
    def _consistent(self) -> Fault:
        kind = self.kind
        if kind in SENSOR_KINDS:
            if self.sensor is None:
                raise ValueError(f"a {kind} fault needs a sensor: ft or encoders")
        elif self.sensor is not None:
            raise ValueError(f"a {kind} fault has no sensor (found sensor: {self.sensor})")
        if kind in JOINT_KINDS and self.joint is None:
            raise ValueError(f"a {kind} fault needs a joint: {', '.join(JOINTS)}")
        if self.joint is not None and kind not in JOINT_KINDS:
            if not (kind in ("noise", "bias") and self.sensor == "encoders"):
                raise ValueError(f"a {kind} fault has no joint (found joint: {self.joint})")
        if kind in ("noise", "bias", "delay", "snag", "joint-weak") and self.value is None:
            raise ValueError(f"a {kind} fault needs a value")
        if self.rate is not None and self.probability is not None:
            raise ValueError("give a rate or a probability, not both")
        if self.when is not None and not self.when.strip():
            raise ValueError("when: expected a state name")
        return self

    # ------------------------------------------------------------------ derived
    @property
    def target(self) -> str:
        """What the fault acts on: ``ft``, ``encoders``, a joint, ``grasp``, ``suture``,
        ``physics``."""
        if self.sensor is not None:
            return self.sensor
        if self.joint is not None:
            return self.joint
        return {"grasp-slip": "grasp", "snag": "suture"}.get(self.kind, "physics")

    @property
    def random(self) -> bool:
        """True for a fault with a random onset (rate or probability)."""
        return self.rate is not None or self.probability is not None

    @property
    def default_duration(self) -> float | None:
        """The duration [s] used when none is given (None: to the end of the run)."""
        if self.duration is not None:
            return self.duration
        if self.kind == "snag":
            return 0.2
        if self.rate is not None:
            return 0.01
        return None

    def describe(self) -> str:
        """A one-line human form (the ``--fault`` syntax)."""
        from suture_engine.faults.syntax import format_fault

        return format_fault(self)
