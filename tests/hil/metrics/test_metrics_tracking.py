"""Tracking error statistics on constructed traces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.metrics import tracking_error


def test_sine_error_known_statistics() -> None:
    t = np.arange(0, 10000) * 0.001                       # 10 s, 10 whole periods of 1 Hz
    target = np.full(t.size, 20.0)
    measured = target + 2.0 * np.sin(2 * np.pi * t)
    s = tracking_error(t, target, measured)
    assert s.mean_error == pytest.approx(0.0, abs=1e-9)
    assert s.mae == pytest.approx(4.0 / math.pi, rel=1e-5)     # mean |2 sin| = 4/π
    assert s.rms == pytest.approx(math.sqrt(2.0), rel=1e-9)
    assert s.max_abs == pytest.approx(2.0, abs=1e-9)
    assert s.max_abs_time_s % 1.0 in (pytest.approx(0.25), pytest.approx(0.75))
    assert s.rms_pct == pytest.approx(100 * math.sqrt(2.0) / 20.0, rel=1e-9)   # 7.07 %
    assert s.max_abs_pct == pytest.approx(10.0, abs=1e-6)


def test_offset_window_dropouts_and_units() -> None:
    t = np.arange(0, 1001) * 0.01
    target = np.where(t < 5.0, 10.0, 30.0)
    measured = target - 0.6                                   # 0.6 g/s short everywhere
    measured[800:810] = np.nan                                # sensor dropout
    s = tracking_error(t, target, measured, t_start=5.0, t_end=10.0)
    assert s.n == 491 and s.dropped == 10
    assert s.mean_error == pytest.approx(-0.6)
    assert s.mae == pytest.approx(0.6) and s.rms == pytest.approx(0.6)
    assert s.mean_error_pct == pytest.approx(-2.0)            # % of the 30 g/s target
    assert s.to_dict()["unit"] == "g/s"


def test_target_on_its_own_timebase() -> None:
    t_set = np.array([0.0, 4.0, 10.0])                        # setpoint log
    set_gps = np.array([20.0, 40.0, 40.0])
    t = np.arange(0, 101) * 0.1                               # 10 Hz measurement
    measured = np.where(t < 4.0, 21.0, 39.0)
    s = tracking_error(t, set_gps, measured, t_target=t_set, interp="previous")
    assert s.mae == pytest.approx(1.0)
    assert s.mean_error == pytest.approx((40 * 1.0 - 61 * 1.0) / 101)
    lin = tracking_error(t, set_gps, measured, t_target=t_set)      # ramps 20 -> 40: not a log
    assert lin.max_abs == pytest.approx(18.5)                 # 21 vs 39.5 at t = 3.9 s
    assert lin.max_abs_time_s == pytest.approx(3.9)
    with pytest.raises(ValueError, match="no finite samples"):
        tracking_error(t, np.full(t.size, 1.0), np.full(t.size, np.nan))
