"""The per-tick trusted constructors build the same frozen objects as the checked ones."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from suture_engine.runtime.observation import (
    CommandMode,
    RobotCommand,
    RobotMeasurement,
    RobotObservation,
    ToolCommand,
    ToolState,
)


def _same(a: object, b: object) -> None:
    assert type(a) is type(b)
    names = [f.name for f in dataclasses.fields(a)]  # type: ignore[arg-type]
    assert list(vars(a)) == names == list(vars(b))
    for name in names:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert np.array_equal(x, y) and not x.flags.writeable
        else:
            assert x == y


def test_trusted_constructors_match_the_checked_ones_and_stay_frozen() -> None:
    q = np.array([0.1, 0.2, 0.3, 0.04])
    w = np.arange(6.0)
    for arr in (q, w):
        arr.flags.writeable = False
    tool = ToolState()
    pairs: list[tuple[Any, Any]] = [
        (RobotMeasurement.trusted(q, w, tool), RobotMeasurement(q, w, tool)),
        (RobotObservation.trusted(q, q, w, tool), RobotObservation(q, q, w, tool)),
        (
            RobotCommand.trusted_position(q.copy(), q.copy(), ToolCommand(jaw_closed=True)),
            RobotCommand.position(q, q, ToolCommand(jaw_closed=True)),
        ),
        (RobotCommand.trusted_torque(q.copy()), RobotCommand.torque(q)),
    ]
    for fast, checked in pairs:
        _same(fast, checked)
        with pytest.raises(dataclasses.FrozenInstanceError):
            fast.q = q
    assert pairs[2][0].mode is CommandMode.POSITION and pairs[3][0].mode is CommandMode.TORQUE
