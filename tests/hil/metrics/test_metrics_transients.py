"""transient_lag reads a controller's lag behind its target flow from the mass it loses, and
judged_recovery turns a recovery that never comes into a failing value with its reason."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.metrics import judged_recovery, transient_lag

T = np.arange(0.0, 60.0, 0.01)
#: a slow-down 25 -> 8 g/s over 3 s, then a step up to 33 g/s
Q = np.interp(T, [0, 10, 13, 30, 30.01, 60], [25.0, 25.0, 8.0, 8.0, 33.0, 33.0])
WINDOWS = [(9.0, 28.0), (29.0, 50.0)]


def _lowpass(y: np.ndarray, tau: float) -> np.ndarray:
    out = np.empty_like(y)
    acc = y[0]
    a = 0.01 / (tau + 0.01)
    for i, v in enumerate(y):
        acc += a * (v - acc)
        out[i] = acc
    return out


@pytest.mark.parametrize("tau", [0.25, 0.5, 2.0])
def test_a_lowpass_reads_its_time_constant(tau: float) -> None:
    m = transient_lag(T, _lowpass(Q, tau), Q, WINDOWS)
    assert m.lag_s == pytest.approx(tau, rel=0.03)
    assert m.window_errors_g[0] > 0 > m.window_errors_g[1]   # over on the fall, under on the rise


def test_a_perfect_follower_reads_zero_and_a_bias_counts() -> None:
    assert transient_lag(T, Q, Q, WINDOWS).lag_s == pytest.approx(0.0, abs=1e-9)
    assert transient_lag(T, 1.02 * Q, Q, WINDOWS).mass_error_pct == pytest.approx(2.0, rel=1e-3)


def test_bad_windows_are_refused() -> None:
    with pytest.raises(ValueError, match="not inside"):
        transient_lag(T, Q, Q, [(50.0, 70.0)])
    with pytest.raises(ValueError, match="does not change"):
        transient_lag(T, Q, Q, [(40.0, 50.0)])


def test_a_recovery_that_never_comes_fails_with_its_reason() -> None:
    value, note = judged_recovery(math.nan, T, t0=18.0)
    assert value == pytest.approx(T[-1] - 18.0) and value > 3.0   # beyond any recovery limit
    assert "never re-entered the ±5% band" in note and "42.0 s" in note
    assert judged_recovery(1.25, T, t0=18.0) == (1.25, "")
