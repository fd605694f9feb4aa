from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.sowing_depth.sampling import paper_sample


def _truth() -> tuple[np.ndarray, np.ndarray]:
    x = np.arange(0.0, 181.0, 0.01)
    depth = np.tile(np.arange(12, dtype=float), (x.size, 1)) + x[:, None] / 1000.0
    return x, depth


def test_three_rows_forty_points_inside_the_headlands() -> None:
    x, depth = _truth()
    s = paper_sample(x, depth, np.random.default_rng(1))
    assert s.shape == (3, 40)
    rows = np.floor(s[:, 0]).astype(int)
    assert len(set(rows)) == 3                       # three different rows
    positions = (s - np.floor(s)) * 1000.0           # the distance encoded in the depth
    assert positions.min() >= 10.0 and positions.max() <= 170.0
    assert np.all(np.diff(positions, axis=1) > 0)    # walking along the row


def test_same_seed_same_sample_and_short_runs_refused() -> None:
    x, depth = _truth()
    a = paper_sample(x, depth, np.random.default_rng(5))
    b = paper_sample(x, depth, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"covered 100\.0 m"):
        paper_sample(x[x <= 100.0], depth[x <= 100.0], np.random.default_rng(0))
