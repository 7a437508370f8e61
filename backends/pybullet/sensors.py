"""Sensor models shared by the backend: encoders and the 6-axis base F/T sensor.

Each measured channel goes through, in order: a transport delay of
``delay_ticks`` control ticks, a constant bias, zero-mean Gaussian noise,
quantisation to a resolution, and dropout (with probability ``dropout`` the
sensor reports its last value again, flagged as not fresh). All randomness
comes from one seeded :class:`numpy.random.Generator` per sensor, and every
tick draws the same number of variates whether or not a sample drops, so a
run is reproducible for a given seed.

Default encoder resolutions are choices (the thesis gives none): 2000
counts per motor revolution behind the Table 3.1 gear ratios for the
revolute joints, 10 µm for the lead-screw insertion stage.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from suture_engine.errors import SutureError
from suture_engine.robot.params import E1, EndoBotParams

__all__ = [
    "BadSensorInput",
    "InvalidSensorModel",
    "Sensor",
    "SensorModel",
    "SensorReading",
    "encoder_model",
    "ft_sensor_model",
]

FloatArray = NDArray[np.float64]
Channels = float | tuple[float, ...]


class InvalidSensorModel(SutureError):
    """A sensor model with an impossible setting.

    Attributes:
        field: the offending setting.
        value: its value.
    """

    code = "invalid-sensor-model"

    def __init__(self, field: str, value: object, reason: str) -> None:
        super().__init__(f"sensor model {field}={value!r}: {reason}")
        self.field = field
        self.value = value


class BadSensorInput(SutureError):
    """True values handed to a sensor with the wrong number of channels.

    Attributes:
        expected: the sensor's channel count.
        got: the shape of the values given.
    """

    code = "bad-sensor-input"

    def __init__(self, expected: int, got: tuple[int, ...]) -> None:
        super().__init__(f"sensor of {expected} channels given values of shape {got}")
        self.expected = expected
        self.got = got


class SensorReading(NamedTuple):
    """One sample of a sensor.

    Attributes:
        values: the measured channels (units of the quantity measured).
        fresh: False when the sample dropped out and ``values`` repeats the last one.
        tick: index of the control tick of this sample.
    """

    values: FloatArray
    fresh: bool
    tick: int


@dataclass(frozen=True)
class SensorModel:
    """Imperfections of a multi-channel sensor; a scalar applies to every channel.

    Attributes:
        resolution: quantisation step per channel (0: none) [channel units].
        noise_std: standard deviation of additive Gaussian noise [channel units].
        bias: constant offset added to every sample [channel units].
        delay_ticks: transport delay [control ticks].
        dropout: probability that a sample is lost and the last one held [-].
    """

    resolution: Channels = 0.0
    noise_std: Channels = 0.0
    bias: Channels = 0.0
    delay_ticks: int = 0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        for name in ("resolution", "noise_std"):
            vals = getattr(self, name)
            for v in vals if isinstance(vals, tuple) else (vals,):
                if not (v >= 0.0 and math.isfinite(v)):
                    raise InvalidSensorModel(name, v, "must be finite and >= 0")
        if self.delay_ticks < 0:
            raise InvalidSensorModel("delay_ticks", self.delay_ticks, "must be >= 0")
        if not 0.0 <= self.dropout < 1.0:
            raise InvalidSensorModel("dropout", self.dropout, "must be in [0, 1)")

    @property
    def ideal(self) -> bool:
        """True when the sensor reports the truth unchanged."""
        settings = (self.resolution, self.noise_std, self.bias)
        flat = [x for v in settings for x in (v if isinstance(v, tuple) else (v,))]
        return all(x == 0.0 for x in flat) and self.delay_ticks == 0 and self.dropout == 0.0


def _broadcast(v: Channels, n: int, name: str) -> FloatArray:
    arr = np.full(n, v, dtype=float) if not isinstance(v, tuple) else np.array(v, dtype=float)
    if arr.shape != (n,):
        raise InvalidSensorModel(name, v, f"needs 1 or {n} values")
    return arr


class Sensor:
    """A stateful sensor applying a :class:`SensorModel` tick by tick.

    An ideal sensor returns the truth as floats (``+ 0.0``, as the general path's
    zero bias and noise do: -0.0 reads 0.0). It still draws its variates unless
    ``draw_when_ideal`` is False, which its owner may set when no other sensor reads
    the same generator (the draws then change nothing a run can see).

    Args:
        model: the imperfections.
        channels: number of channels.
        rng: the seeded generator this sensor draws from.
        draw_when_ideal: draw the tick's variates even when the model is ideal.
    """

    def __init__(
        self,
        model: SensorModel,
        channels: int,
        rng: np.random.Generator,
        draw_when_ideal: bool = True,
    ) -> None:
        self._model = model
        self.channels = channels
        self.draw_when_ideal = draw_when_ideal
        self._rng = rng
        self._ideal = model.ideal
        self._res = _broadcast(model.resolution, channels, "resolution")
        self._std = _broadcast(model.noise_std, channels, "noise_std")
        self._bias = _broadcast(model.bias, channels, "bias")
        step = self._res > 0.0
        self._quantised = step if step.any() else None
        self._noise = np.empty(channels)  # this tick's Gaussian draws
        self._buffer: deque[FloatArray] = deque(maxlen=model.delay_ticks + 1)
        self._last: FloatArray | None = None
        self._tick = 0

    def __repr__(self) -> str:
        return f"Sensor(channels={self.channels}, model={self.model!r})"

    @property
    def model(self) -> SensorModel:
        """The imperfections (fixed for the sensor's life)."""
        return self._model

    @property
    def rng(self) -> np.random.Generator:
        """The generator this sensor draws from (possibly shared with other sensors)."""
        return self._rng

    def measure(self, truth: Sequence[float] | FloatArray) -> SensorReading:
        """Sample the sensor once per control tick.

        Args:
            truth: the true channel values this tick.

        Returns:
            The reading (delayed, biased, noisy, quantised, possibly held).
        """
        if self._ideal:
            if self.draw_when_ideal:
                self._rng.standard_normal(out=self._noise)
                self._rng.random()
            ideal = np.array(truth, dtype=float)
            ideal += 0.0
            if ideal.shape != (self.channels,):
                raise BadSensorInput(self.channels, ideal.shape)
            tick = self._tick
            self._tick += 1
            return SensorReading(ideal, True, tick)
        true = np.array(truth, dtype=float)
        if true.shape != (self.channels,):
            raise BadSensorInput(self.channels, true.shape)
        self._buffer.append(true)
        delayed = self._buffer[0]  # the oldest kept sample = delay_ticks ago (or the first)
        noise = self._rng.standard_normal(out=self._noise)
        lost = self._rng.random() < self._model.dropout
        value = delayed + self._bias + self._std * noise
        if self._quantised is not None:
            res = self._res[self._quantised]
            value[self._quantised] = np.round(value[self._quantised] / res) * res
        tick = self._tick
        self._tick += 1
        if lost and self._last is not None:
            return SensorReading(self._last.copy(), False, tick)
        self._last = value
        return SensorReading(value.copy(), True, tick)


def encoder_model(
    params: EndoBotParams | None = None,
    counts_per_motor_rev: float = 2000.0,
    insertion_resolution: float = 1e-5,
    noise_std: Channels = 0.0,
    bias: Channels = 0.0,
    delay_ticks: int = 0,
    dropout: float = 0.0,
) -> SensorModel:
    """Joint encoders of one EndoBot: only positions are measured.

    Args:
        params: robot parameters, for the gear ratios (None: E1).
        counts_per_motor_rev: encoder counts per motor revolution (0: no quantisation).
        insertion_resolution: insertion-stage resolution [m] (0: none).
        noise_std: Gaussian noise [rad, rad, rad, m].
        bias: constant offset [rad, rad, rad, m].
        delay_ticks: transport delay [ticks].
        dropout: probability of a lost sample [-].

    Returns:
        The sensor model (4 channels).
    """
    p = params or E1
    res: list[float] = []
    for j in p.joints[:3]:
        counts = counts_per_motor_rev * j.motor.gear_ratio
        res.append(2.0 * math.pi / counts if counts > 0.0 else 0.0)
    res.append(insertion_resolution)
    return SensorModel(tuple(res), noise_std, bias, delay_ticks, dropout)


def ft_sensor_model(
    force_noise_std: float = 0.0,
    torque_noise_std: float = 0.0,
    force_resolution: float = 0.0,
    torque_resolution: float = 0.0,
    bias: Channels = 0.0,
    delay_ticks: int = 0,
    dropout: float = 0.0,
) -> SensorModel:
    """The 6-axis base force/torque sensor (Fx, Fy, Fz [N], Mx, My, Mz [N*m]).

    Args:
        force_noise_std: force noise [N].
        torque_noise_std: torque noise [N*m].
        force_resolution: force quantisation [N].
        torque_resolution: torque quantisation [N*m].
        bias: offset per channel [N, N, N, N*m, N*m, N*m].
        delay_ticks: transport delay [ticks].
        dropout: probability of a lost sample [-].

    Returns:
        The sensor model (6 channels).
    """
    return SensorModel(
        (force_resolution,) * 3 + (torque_resolution,) * 3,
        (force_noise_std,) * 3 + (torque_noise_std,) * 3,
        bias,
        delay_ticks,
        dropout,
    )
