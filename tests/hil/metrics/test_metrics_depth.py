"""GB/T 20865 depth statistics and [D]-style sampling on constructed data."""

from __future__ import annotations

import json
import math
import statistics

import numpy as np
import pytest

from hil.metrics import depth_statistics, qualified_band, sample_depth


def constructed() -> np.ndarray:
    """3 rows x 40: 112 inliers at 29/31 mm, 4 clods at 15 mm (row 0), 4 at 46 mm (row 2)."""
    return np.array([
        [29.0] * 18 + [31.0] * 18 + [15.0] * 4,
        [29.0] * 20 + [31.0] * 20,
        [29.0] * 18 + [31.0] * 18 + [46.0] * 4,
    ])


def test_band_rule() -> None:
    assert qualified_band(30.0) == (20.0, 40.0)
    assert qualified_band(50.0) == (40.0, 60.0)
    assert qualified_band(25.0) == (20.0, 30.0)       # under 30 mm: ±5 mm
    with pytest.raises(ValueError):
        qualified_band(0.0)


def test_statistics_with_outliers() -> None:
    x = constructed()
    s = depth_statistics(x, 30.0)
    flat = x.ravel().tolist()
    assert (s.n, s.n_qualified, s.n_below, s.n_above) == (120, 112, 4, 4)
    assert s.pass_rate_pct == pytest.approx(100 * 112 / 120)            # 93.33 %
    assert s.mean_mm == pytest.approx(3604 / 120)                         # 30.033 mm
    assert s.sd_mm == pytest.approx(statistics.stdev(flat))               # ddof = 1
    # by hand: Σx² = 56·29² + 56·31² + 4·15² + 4·46² = 110,276
    assert s.sd_mm == pytest.approx(math.sqrt((110276 - 3604**2 / 120) / 119))   # 4.1362 mm
    assert s.cv_pct == pytest.approx(100 * s.sd_mm / s.mean_mm)           # 13.77 %
    assert s.inlier_mean_mm == pytest.approx(30.0)
    assert s.inlier_sd_mm == pytest.approx(math.sqrt(112 / 111))          # 1.0045 mm
    assert s.inlier_cv_pct == pytest.approx(100 * math.sqrt(112 / 111) / 30.0)  # 3.35 %
    assert s.row_mean_mm == pytest.approx((28.5, 30.0, 31.6))
    assert s.row_pass_rate_pct == pytest.approx((90.0, 100.0, 90.0))
    assert json.loads(json.dumps(s.to_dict()))["band_high_mm"] == 40.0


def test_band_edges_are_qualified_and_band_override() -> None:
    s = depth_statistics(np.array([20.0, 40.0, 19.99, 40.01]), 30.0)
    assert s.n_qualified == 2 and s.pass_rate_pct == 50.0
    narrow = depth_statistics(constructed(), 30.0, band_mm=(29.5, 30.5))
    assert narrow.n_qualified == 0 and math.isnan(narrow.inlier_mean_mm)
    with pytest.raises(ValueError, match="non-finite"):
        depth_statistics(np.array([30.0, np.nan]))


def test_sampler_equally_spaced_without_headlands() -> None:
    positions = np.arange(1801) * 0.1                      # 0 .. 180 m in 0.1 m cells
    depth = 1000.0 * np.arange(3)[:, None] + positions     # depth encodes row and place
    got = sample_depth(positions, depth)
    expected = 10.0 + 4.0 * (np.arange(40) + 0.5)          # 12, 16, ... 168 m
    assert got.depth_mm.shape == (3, 40) and got.rows == (0, 1, 2)
    assert np.allclose(got.positions_m, expected)
    assert np.allclose(got.depth_mm, 1000.0 * np.arange(3)[:, None] + expected, atol=1e-9)
    two = sample_depth(positions, depth, rows=[2, 0], points=4, headland_m=30.0)
    assert np.allclose(two.depth_mm[0], 2000.0 + np.array([45.0, 75.0, 105.0, 135.0]))


def test_sampler_jitter_is_seeded_and_stays_in_its_segment() -> None:
    positions = np.arange(1801) * 0.1
    depth = np.tile(positions, (3, 1))
    a = sample_depth(positions, depth, jitter=1.0, seed=7)
    b = sample_depth(positions, depth, jitter=1.0, seed=7)
    c = sample_depth(positions, depth, jitter=1.0, seed=8)
    assert np.array_equal(a.depth_mm, b.depth_mm)
    assert not np.array_equal(a.depth_mm, c.depth_mm)
    centres = 10.0 + 4.0 * (np.arange(40) + 0.5)
    assert np.all(np.abs(a.positions_m - centres) <= 2.0)
    assert np.abs(a.positions_m - centres).max() > 1.0     # it does move the points
    assert not np.array_equal(a.positions_m[0], a.positions_m[1])   # each row its own
    assert np.all(np.abs(a.depth_mm - a.positions_m) <= 0.05 + 1e-9)   # nearest cell


def test_sampler_rejects_bad_input() -> None:
    positions = np.arange(101) * 0.2                       # a 20 m run
    with pytest.raises(ValueError, match="headlands"):
        sample_depth(positions, np.zeros((3, 101)))
    with pytest.raises(ValueError, match="rows"):
        sample_depth(positions, np.zeros((3, 101)), headland_m=1.0, rows=[3])
    with pytest.raises(ValueError, match=r"\(rows, 101\)"):
        sample_depth(positions, np.zeros((101, 3)), headland_m=1.0)
