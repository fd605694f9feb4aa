"""Flow map: the fit to [F]'s bench points, and what Table 1 says about per-row flow."""

from __future__ import annotations

import pytest

from plant_emulators.fertilizer import paper_data as paper
from plant_emulators.fertilizer.flow_map import FlowMap, fit_power_law

FIT_TOLERANCE_GPS = 0.5
"""Largest residual accepted at [F]'s three bench points (g/s); the fit's own is 0.44."""


@pytest.fixture
def flow_map(rig_config) -> FlowMap:
    return FlowMap.from_config(rig_config.meter)


def test_config_holds_the_least_squares_fit_of_the_bench_points(rig_config):
    c, p = fit_power_law(paper.BENCH_SHAFT_RPM, paper.BENCH_TARGET_GPS)
    assert rig_config.meter.flow_coeff_gps == pytest.approx(c, abs=5e-4)
    assert rig_config.meter.flow_exponent == pytest.approx(p, abs=5e-5)


def test_fit_reproduces_bench_flows(flow_map):
    for n, q in zip(paper.BENCH_SHAFT_RPM, paper.BENCH_TARGET_GPS, strict=True):
        assert abs(flow_map.flow_gps(n) - q) < FIT_TOLERANCE_GPS


def test_grams_per_rev_falls_with_speed(flow_map):
    per_rev = [flow_map.grams_per_rev(n) for n in paper.BENCH_SHAFT_RPM]
    assert per_rev[0] > per_rev[1] > per_rev[2]
    for got, want in zip(per_rev, (115.0, 97.0, 82.5), strict=True):
        assert got == pytest.approx(want, rel=0.015)


def test_map_is_continuous_and_linear_below_the_knee(flow_map):
    knee = flow_map.linear_below_rpm
    assert flow_map.flow_gps(knee - 1e-9) == pytest.approx(flow_map.flow_gps(knee), rel=1e-6)
    assert flow_map.flow_gps(knee / 2) == pytest.approx(flow_map.flow_gps(knee) / 2)
    assert flow_map.flow_gps(0.0) == 0.0
    assert flow_map.flow_gps(-3.0) == 0.0
    assert flow_map.grams_per_rev(1.0) == pytest.approx(flow_map.grams_per_rev(knee))


def test_inverse_map(flow_map):
    for n in (1.0, 4.0, 12.0, 21.0, 32.0, 40.0):
        assert flow_map.speed_for_flow(flow_map.flow_gps(n)) == pytest.approx(n)
    assert flow_map.speed_for_flow(0.0) == 0.0


def test_grams_per_rev_needs_a_turning_shaft(flow_map):
    with pytest.raises(ValueError, match="turning"):
        flow_map.grams_per_rev(0.0)


def test_table1_is_consistent_with_per_row_flow_over_about_ten_seconds(flow_map):
    """Table 1's weighed masses divided by the per-row map flow give ~10 s for every speed.

    With the 4-row total the implied collection times would be ~2.5 s and would not match
    [F]'s 1 s windows any better; the per-row reading is the consistent one.
    """
    times = [w / flow_map.flow_gps(n)
             for n, w in zip(paper.TABLE1_SHAFT_RPM, paper.TABLE1_WEIGHED_G, strict=True)]
    mean = sum(times) / len(times)
    assert 9.5 < mean < 10.8
    assert max(abs(t / mean - 1.0) for t in times) < 0.08


def test_fit_needs_two_points():
    with pytest.raises(ValueError):
        fit_power_law([12.0], [23.0])
