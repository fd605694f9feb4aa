"""Step-response metrics on synthetic signals with known answers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hil.metrics import smooth, step_response

DT = 0.01
T0 = 1.0
TAU = 0.5
t = np.arange(1200) * DT          # 0 .. 11.99 s at 100 Hz


def first_order(y0: float, target: float, *, tau: float = TAU, delay: float = 0.0,
                times: np.ndarray = t) -> np.ndarray:
    s = np.clip(times - T0 - delay, 0.0, None)
    return y0 + (target - y0) * (1.0 - np.exp(-s / tau))


def second_order(y0: float, target: float, zeta: float, wn: float,
                 times: np.ndarray = t) -> np.ndarray:
    s = np.clip(times - T0, 0.0, None)
    root = math.sqrt(1.0 - zeta * zeta)
    unit = 1.0 - np.exp(-zeta * wn * s) / root * np.sin(wn * root * s + math.acos(zeta))
    return y0 + (target - y0) * unit


def overshoot_formula(zeta: float) -> float:
    return 100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta * zeta))


def test_first_order_known_answers() -> None:
    m = step_response(t, first_order(10.0, 30.0), t0=T0, target=30.0, y0=10.0)
    # sample times are reported: exact to one sample period
    assert m.rise_time_s == pytest.approx(TAU * math.log(9), abs=DT)          # 1.0986 s
    assert m.response_time_s == pytest.approx(TAU * math.log(20), abs=DT)     # 1.4979 s
    assert m.settling_time_s == pytest.approx(TAU * math.log(50), abs=DT)     # 1.9560 s
    assert m.delay_s == pytest.approx(TAU * math.log(1 / 0.95), abs=DT)       # 0.0256 s
    assert m.overshoot_pct == 0.0
    assert m.steady_state_error_pct < 1e-3
    assert m.step == 20.0
    assert m.notes == ()


def test_dead_time_adds_to_response_not_to_rise() -> None:
    m = step_response(t, first_order(10.0, 30.0, delay=0.3), t0=T0, target=30.0, y0=10.0)
    assert m.rise_time_s == pytest.approx(TAU * math.log(9), abs=DT)
    assert m.response_time_s == pytest.approx(0.3 + TAU * math.log(20), abs=DT)
    assert m.delay_s == pytest.approx(0.3 + TAU * math.log(1 / 0.95), abs=DT)


@pytest.mark.parametrize("zeta", [0.4, 0.7])
def test_second_order_overshoot(zeta: float) -> None:
    y = second_order(10.0, 30.0, zeta, 3.0)
    raw = step_response(t, y, t0=T0, target=30.0, y0=10.0, filter_kind="none")
    filt = step_response(t, y, t0=T0, target=30.0, y0=10.0)
    expected = overshoot_formula(zeta)                                # 25.38 %, 4.60 %
    assert raw.overshoot_pct == pytest.approx(expected, abs=0.02)
    # the default median trims a sharp peak a little (documented: ~0.3 points at wn = 3)
    assert filt.overshoot_pct == pytest.approx(expected, abs=0.4)
    assert filt.overshoot_pct <= raw.overshoot_pct
    peak_time = math.pi / (3.0 * math.sqrt(1 - zeta * zeta))
    assert raw.peak_time_s == pytest.approx(peak_time, abs=DT)
    # response time against a dense evaluation of the same formula
    fine = np.arange(0.0, 11.0, 1e-4) + T0
    outside = np.abs(second_order(10.0, 30.0, zeta, 3.0, fine) - 30.0) >= 0.05 * 20.0
    reference = fine[np.nonzero(outside)[0][-1]] - T0
    assert raw.response_time_s == pytest.approx(reference, abs=DT + 1e-4)
    assert filt.response_time_s == pytest.approx(reference, abs=2 * DT)


def test_step_down() -> None:
    m = step_response(t, first_order(30.0, 10.0), t0=T0, target=10.0, y0=30.0)
    assert m.step == -20.0
    assert m.rise_time_s == pytest.approx(TAU * math.log(9), abs=DT)
    assert m.response_time_s == pytest.approx(TAU * math.log(20), abs=DT)
    assert m.overshoot_pct == 0.0
    y2 = second_order(30.0, 10.0, 0.5, 3.0)                         # dips below 10
    m2 = step_response(t, y2, t0=T0, target=10.0, y0=30.0, filter_kind="none")
    assert m2.overshoot_pct == pytest.approx(overshoot_formula(0.5), abs=0.02)   # 16.30 %
    assert m2.peak_value == pytest.approx(10.0 - 0.163 * 20.0, abs=0.01)


def test_noise_does_not_fool_it() -> None:
    """White noise of SD 1 % of the step plus single wild samples (±50 % of the step).

    Stated tolerances at the defaults (median over 0.2 s): rise ±0.05 s, response ±0.1 s,
    overshoot < 1.5 % (none really), steady-state error < 0.1 % from the white noise plus
    |spike| / n for each wild sample inside the steady window (it is a mean of raw samples).
    """
    clean = step_response(t, first_order(10.0, 30.0), t0=T0, target=30.0, y0=10.0)
    for seed in range(5):
        rng = np.random.default_rng(seed)
        y = first_order(10.0, 30.0) + rng.normal(0.0, 0.2, t.size)
        spikes = rng.choice(np.arange(250, 1190), size=6, replace=False)
        y[spikes] += rng.choice([-10.0, 10.0], size=6)
        m = step_response(t, y, t0=T0, target=30.0, y0=10.0)
        assert abs(m.rise_time_s - clean.rise_time_s) <= 0.05
        assert abs(m.response_time_s - clean.response_time_s) <= 0.1
        assert m.overshoot_pct < 1.5
        in_window = spikes >= t.size - 500
        spike_part = 10.0 * in_window.sum() / 500 / 30.0 * 100.0
        assert m.steady_state_error_pct < 0.1 + spike_part
        assert m.noise_sd == pytest.approx(0.2, rel=0.2)


def test_single_spike_needs_the_filter() -> None:
    y = first_order(10.0, 30.0)
    y[900] += 5.0                          # one sample 25 % of the step high, at t = 9 s
    raw = step_response(t, y, t0=T0, target=30.0, y0=10.0, filter_kind="none")
    assert raw.response_time_s == pytest.approx(9.0 - T0 + DT, abs=1e-9)     # fooled
    assert raw.overshoot_pct == pytest.approx(25.0, abs=0.01)                 # fooled
    m = step_response(t, y, t0=T0, target=30.0, y0=10.0)
    assert m.response_time_s == pytest.approx(TAU * math.log(20), abs=DT)
    assert m.overshoot_pct == 0.0


def test_never_settles() -> None:
    y = first_order(10.0, 30.0) + 4.0 * np.sin(np.pi * t) * (t > 3.0)     # ±20 % at 0.5 Hz
    m = step_response(t, y, t0=T0, target=30.0, y0=10.0, t_end=11.5)     # ends on a trough
    assert math.isnan(m.response_time_s)
    assert math.isnan(m.settling_time_s)
    assert any("never entered and stayed in the ±5% band" in n for n in m.notes)
    assert m.overshoot_pct == pytest.approx(20.0, abs=0.3)   # the 4.0 swing is 20 % of 20


def test_stuck_short_of_target() -> None:
    y = first_order(0.0, 16.0)                               # asked for 20, gets 16
    m = step_response(t, y, t0=T0, target=20.0, y0=0.0)
    assert math.isnan(m.rise_time_s)                         # never reaches 90 % (18)
    assert math.isnan(m.response_time_s)
    assert m.overshoot_pct == 0.0
    assert m.steady_state_error_pct == pytest.approx(20.0, abs=1e-3)
    assert any("never reached 90%" in n for n in m.notes)


def test_wide_band_without_rise_uses_own_band_test() -> None:
    y = first_order(0.0, 17.0)                               # 85 %: inside a ±20 % band
    m = step_response(t, y, t0=T0, target=20.0, y0=0.0, band=0.2)
    assert math.isnan(m.rise_time_s)
    assert m.response_time_s == pytest.approx(TAU * math.log(17.0 / 1.0), abs=DT)


def test_zero_order_held_1hz_sensor() -> None:
    """A 1 Hz sensor sampling a tau = 1 s response, held at 100 Hz; reports at t0 + 0.5 + k."""
    true = first_order(0.0, 20.0, tau=1.0)
    held = np.zeros_like(true)
    report = np.arange(150, t.size, 100)                     # samples at t0 + 0.5, 1.5, ...
    for i, j in enumerate(report):
        held[j:report[i + 1] if i + 1 < report.size else None] = true[j]
    m = step_response(t, held, t0=T0, target=20.0, y0=0.0)
    # 1 - e^-0.5 = 0.39 (>10 %), 1 - e^-2.5 = 0.918 (>90 %), 1 - e^-3.5 = 0.970 (>95 %)
    assert m.rise_time_s == pytest.approx(2.0, abs=1e-9)
    assert m.response_time_s == pytest.approx(3.5, abs=1e-9)
    assert m.delay_s == pytest.approx(0.5, abs=1e-9)
    assert m.overshoot_pct == 0.0
    assert m.noise_sd == 0.0


def test_entering_just_before_the_end_is_not_a_response() -> None:
    end = T0 + TAU * math.log(20) + 0.5
    m = step_response(t, first_order(10.0, 30.0), t0=T0, target=30.0, y0=10.0, t_end=end,
                      steady_window_s=1.0)
    assert math.isnan(m.response_time_s)
    assert any("min_hold_s" in n for n in m.notes)
    ok = step_response(t, first_order(10.0, 30.0), t0=T0, target=30.0, y0=10.0, t_end=end,
                       steady_window_s=1.0, min_hold_s=0.25)
    assert ok.response_time_s == pytest.approx(TAU * math.log(20), abs=DT)


def test_steady_state_window_and_y0_estimate() -> None:
    rng = np.random.default_rng(3)
    y = first_order(10.0, 30.3) + rng.normal(0.0, 0.2, t.size)   # 1 % high
    m = step_response(t, y, t0=T0, target=30.0)                   # y0 from the pre-step median
    assert m.y0 == pytest.approx(10.0, abs=0.06)
    assert m.steady_state_error_pct == pytest.approx(1.0, abs=0.1)
    short = step_response(t, y, t0=T0, target=30.0, steady_window_s=20.0)
    assert math.isnan(short.steady_state_error_pct)


def test_band_too_narrow_for_the_noise_is_flagged() -> None:
    rng = np.random.default_rng(4)
    y = first_order(10.0, 30.0) + rng.normal(0.0, 1.0, t.size)   # SD 5 % of the step
    m = step_response(t, y, t0=T0, target=30.0, y0=10.0, band=0.01)
    assert any("widen the band" in n for n in m.notes)


def test_nan_samples_dropped_and_bad_input_rejected() -> None:
    y = first_order(10.0, 30.0)
    y[500:510] = np.nan
    m = step_response(t, y, t0=T0, target=30.0, y0=10.0)
    assert m.response_time_s == pytest.approx(TAU * math.log(20), abs=DT)
    assert "10 non-finite samples dropped" in m.notes
    with pytest.raises(ValueError, match="zero step"):
        step_response(t, y, t0=T0, target=10.0, y0=10.0)
    with pytest.raises(ValueError, match="shape"):
        step_response(t, y[:-1], t0=T0, target=30.0, y0=10.0)
    with pytest.raises(ValueError, match="increasing"):
        step_response(t[::-1], y, t0=T0, target=30.0, y0=10.0)
    with pytest.raises(ValueError, match="2 samples"):
        step_response(t, y, t0=20.0, target=30.0, y0=10.0)


def test_to_dict_is_json() -> None:
    m = step_response(t, first_order(10.0, 30.0), t0=T0, target=30.0, y0=10.0)
    d = json.loads(json.dumps(m.to_dict()))
    assert d["response_time_s"] == pytest.approx(m.response_time_s)
    assert d["filter"] == "median" and d["filter_samples"] == 21


def test_smooth() -> None:
    x = np.full(101, 5.0)
    x[40:50] = 100.0                                          # a burst of 10 samples
    assert np.array_equal(smooth(x, 21, "median"), np.full(101, 5.0))
    ramp = np.arange(50.0)
    assert np.array_equal(smooth(ramp, 21, "median")[10:-10], ramp[10:-10])   # monotone kept
    assert smooth(ramp, 21, "median")[-1] == 44.0       # truncated end window: last 11 samples
    assert smooth(ramp, 5, "mean")[10] == pytest.approx(10.0)
    with pytest.raises(ValueError, match="odd"):
        smooth(ramp, 4, "mean")


def test_recovery_time_back_in_band_never_left_and_not_back() -> None:
    from hil.metrics import recovery_time

    t = np.arange(0.0, 20.0, 0.01)
    dip = np.where((t >= 10.0) & (t < 12.0), 20.0, 34.0)          # 41 % low for 2 s
    assert recovery_time(t, dip, t0=10.0, target=34.0, filter_kind="none") == \
        pytest.approx(2.0, abs=0.011)
    flat = np.full_like(t, 34.5)                                    # within 5 % throughout
    assert recovery_time(t, flat, t0=10.0, target=34.0) == 0.0
    stuck = np.where(t >= 10.0, 30.0, 34.0)                         # 12 % low to the end
    assert math.isnan(recovery_time(t, stuck, t0=10.0, target=34.0))
    late = np.where((t >= 10.0) & (t < 19.5), 20.0, 34.0)           # back for only 0.5 s
    assert math.isnan(recovery_time(t, late, t0=10.0, target=34.0, filter_kind="none"))


def test_mean_over_whole_ripple_periods_is_judged_only_where_its_window_is_whole() -> None:
    """A step to 23 with a 2.5 Hz ripple of 15 % (a fluted roller at 12.5 r/min): a mean over
    three ripple periods (1.2 s) removes it; near the end of the record the truncated window
    would let it through, so the last half window is not judged."""
    ripple = 0.15 * 23.0 * np.sin(2 * math.pi * 2.5 * t + 3.2)
    y = first_order(0.0, 23.0, tau=0.1) + np.where(t >= T0, ripple, 0.0)
    m = step_response(t, y, t0=T0, target=23.0, y0=0.0, filter_kind="mean", filter_s=1.2)
    assert m.overshoot_pct < 0.5
    assert m.response_time_s < 1.0
    # the truncated end windows do let the ripple through: judged there, it would be overshoot
    from hil.metrics.step import smooth as smooth_
    tail = smooth_(y, 121, "mean")[-60:]
    assert (tail.max() - 23.0) / 23.0 * 100 > 2.5
    # and a recovery judged the same way is not pushed to the end by the truncated windows
    from hil.metrics import recovery_time
    assert recovery_time(t, y, t0=T0, target=23.0, filter_kind="mean", filter_s=1.2) < 1.0
