"""The sensor model: delay, sample-and-hold, gain/offset, seeded noise, quantisation."""

from __future__ import annotations

import numpy as np
import pytest

from hil.ownrig.config import SentSignal
from hil.ownrig.sensor import SensorModel


def sensor(**kw: float) -> SensorModel:
    return SensorModel(SentSignal(fmu="y", **kw), np.random.default_rng(1))


def test_gain_offset_and_quantum() -> None:
    s = sensor(gain=2.0, offset=1.0, quantum=0.5)
    assert s.sample(0.0, 1.1) == 3.0          # 2*1.1+1 = 3.2 -> 3.0
    assert s.sample(0.0, 1.2) == 3.5          # 3.4 -> 3.5


def test_delay_reads_the_value_that_long_ago() -> None:
    s = sensor(delay_ms=5.0)
    for k in range(20):
        s.record(k * 0.001, float(k))
    assert s.sample(0.019, 19.0) == 14.0
    early = sensor(delay_ms=5.0)
    for k in range(3):
        early.record(k * 0.001, float(k + 1))
    assert early.sample(0.002, 3.0) == 1.0    # before the first delay: the first value


def test_hold_samples_every_period_only() -> None:
    s = sensor(hold_ms=100.0)
    assert s.sample(0.0, 1.0) == 1.0
    assert s.sample(0.05, 2.0) == 1.0
    assert s.sample(0.1, 3.0) == 3.0
    assert s.sample(0.15, 4.0) == 3.0


def test_noise_is_seeded_and_of_its_size() -> None:
    a = [sensor(noise_sd=0.5).sample(0.0, 10.0) for _ in range(1)]
    b = [sensor(noise_sd=0.5).sample(0.0, 10.0) for _ in range(1)]
    assert a == b and a[0] != 10.0
    s = sensor(noise_sd=0.5)
    values = np.array([s.sample(0.0, 10.0) for _ in range(4000)])
    assert values.mean() == pytest.approx(10.0, abs=0.05)
    assert values.std() == pytest.approx(0.5, rel=0.05)


def test_rate_over_a_window_of_a_cumulative_value() -> None:
    s = sensor(rate_window_ms=100.0)
    for k in range(301):                  # 2 g per ms: 2000 g/s
        s.record(k * 0.001, 2.0 * k)
    assert s.sample(0.3, 600.0) == pytest.approx(2000.0)
    young = sensor(rate_window_ms=100.0)
    for k in range(51):
        young.record(k * 0.001, 2.0 * k)
    assert young.sample(0.05, 100.0) == pytest.approx(1000.0)   # half a window summed so far
