"""Sensor models: quantisation, noise statistics, bias, delay, dropout, determinism."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from backends.pybullet.sensors import (
    BadSensorInput,
    InvalidSensorModel,
    Sensor,
    SensorModel,
    encoder_model,
    ft_sensor_model,
)
from suture_engine.robot.params import E1


def _run(model: SensorModel, truth: np.ndarray, seed: int = 0) -> np.ndarray:
    s = Sensor(model, truth.shape[1], np.random.default_rng(seed))
    return np.array([s.measure(t).values for t in truth])


def test_ideal_sensor_is_transparent() -> None:
    truth = np.random.default_rng(3).normal(size=(50, 4))
    assert SensorModel().ideal
    np.testing.assert_array_equal(_run(SensorModel(), truth), truth)


def test_encoder_quantisation_from_counts_per_rev() -> None:
    model = encoder_model(E1, counts_per_motor_rev=500.0, insertion_resolution=1e-4)
    step = 2 * math.pi / (500.0 * 134.0)
    assert model.resolution == pytest.approx((step, step, 2 * math.pi / (500 * 72.88), 1e-4))
    truth = np.array([[0.123456, -0.5, 1.0, 0.012345]])
    out = _run(model, truth)[0]
    res = np.array(model.resolution)  # type: ignore[arg-type]
    np.testing.assert_allclose(out / res, np.round(out / res), atol=1e-9)
    assert np.all(np.abs(out - truth[0]) <= res / 2 + 1e-15)


def test_noise_and_bias_statistics() -> None:
    truth = np.zeros((20000, 6))
    model = ft_sensor_model(force_noise_std=0.2, torque_noise_std=0.01, bias=0.5)
    out = _run(model, truth)
    np.testing.assert_allclose(out.mean(axis=0), 0.5, atol=0.01)
    np.testing.assert_allclose(out.std(axis=0), [0.2] * 3 + [0.01] * 3, rtol=0.03)


def test_delay_in_ticks() -> None:
    truth = np.arange(10.0).reshape(-1, 1)
    out = _run(SensorModel(delay_ticks=3), truth)[:, 0]
    np.testing.assert_array_equal(out, [0, 0, 0, 0, 1, 2, 3, 4, 5, 6])


def test_dropout_holds_last_value_and_flags_it() -> None:
    truth = np.arange(2000.0).reshape(-1, 1)
    s = Sensor(SensorModel(dropout=0.3), 1, np.random.default_rng(5))
    readings = [s.measure(t) for t in truth]
    lost = [r for r in readings if not r.fresh]
    assert 0.25 < len(lost) / len(readings) < 0.35
    for prev, cur in itertools.pairwise(readings):
        if not cur.fresh:
            np.testing.assert_array_equal(cur.values, prev.values)
        else:
            assert cur.values[0] == truth[cur.tick, 0]
    assert [r.tick for r in readings] == list(range(2000))


def test_same_seed_same_stream_other_seed_differs() -> None:
    model = SensorModel(noise_std=0.1, dropout=0.1, resolution=0.01, bias=0.2, delay_ticks=2)
    truth = np.random.default_rng(0).normal(size=(300, 4))
    a, b = _run(model, truth, seed=7), _run(model, truth, seed=7)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, _run(model, truth, seed=8))


def test_invalid_models_are_typed_errors() -> None:
    with pytest.raises(InvalidSensorModel) as err:
        SensorModel(dropout=1.0)
    assert err.value.field == "dropout"
    with pytest.raises(InvalidSensorModel):
        SensorModel(noise_std=-1.0)
    with pytest.raises(InvalidSensorModel):
        Sensor(SensorModel(bias=(1.0, 2.0)), 4, np.random.default_rng(0))


class _ReferenceSensor:
    """The sensor as first written (one numpy path for every model): the oracle."""

    def __init__(self, model: SensorModel, n: int, rng: np.random.Generator) -> None:
        self.model, self.n, self.rng = model, n, rng
        self.res = np.broadcast_to(np.array(model.resolution, float), n)
        self.std = np.broadcast_to(np.array(model.noise_std, float), n)
        self.bias = np.broadcast_to(np.array(model.bias, float), n)
        self.buf: list[np.ndarray] = []
        self.last: np.ndarray | None = None

    def measure(self, truth: np.ndarray) -> tuple[np.ndarray, bool]:
        self.buf = ([*self.buf, np.array(truth, float)])[-(self.model.delay_ticks + 1) :]
        noise = self.rng.standard_normal(self.n)
        lost = self.rng.random() < self.model.dropout
        value = self.buf[0] + self.bias + self.std * noise
        step = self.res > 0.0
        if step.any():
            value[step] = np.round(value[step] / self.res[step]) * self.res[step]
        if lost and self.last is not None:
            return self.last.copy(), False
        self.last = value
        return value.copy(), True


@pytest.mark.parametrize(
    "model",
    [
        SensorModel(),
        SensorModel(noise_std=(0.02, 0.02, 0.02, 0.0, 0.0, 0.0), delay_ticks=2),
        SensorModel(resolution=0.05, bias=(0.1, -0.2, 0.0, 0.0, 1.0, 2.0), dropout=0.2),
        SensorModel(resolution=(0.0, 0.01, 0.0, 1e-3, 0.0, 0.5), noise_std=0.3, delay_ticks=1),
    ],
)
def test_readings_equal_the_reference_sensor_to_the_bit(model: SensorModel) -> None:
    """Signed zeros and small negatives included (quantised -0.01 reads -0.0)."""
    truth = np.random.default_rng(4).normal(scale=0.1, size=(400, 6))
    truth[::5] = -0.0
    truth[1::9] = -0.004
    ref = _ReferenceSensor(model, 6, np.random.default_rng(9))
    sensor = Sensor(model, 6, np.random.default_rng(9))
    for k, t in enumerate(truth):
        values, fresh = ref.measure(t)
        reading = sensor.measure(t.tolist() if k % 2 else t)
        assert reading.values.tobytes() == values.tobytes()
        assert reading.fresh == fresh and reading.tick == k


def test_an_ideal_sensor_draws_unless_told_it_need_not() -> None:
    """The draws keep a generator shared with an imperfect sensor on its stream."""
    for draw in (True, False):
        rng, twin = np.random.default_rng(2), np.random.default_rng(2)
        s = Sensor(SensorModel(), 3, rng, draw_when_ideal=draw)
        assert s.measure([1.0, -0.0, 2.0]).values.tolist() == [1.0, 0.0, 2.0]
        if draw:
            twin.standard_normal(3)
            twin.random()
        assert rng.random() == twin.random()


def test_wrong_channel_count_is_a_typed_error() -> None:
    for model in (SensorModel(), SensorModel(noise_std=0.1)):
        with pytest.raises(BadSensorInput) as err:
            Sensor(model, 4, np.random.default_rng(0)).measure([1.0, 2.0, 3.0])
        assert err.value.expected == 4 and err.value.got == (3,)
