"""Sampling the truth the way [D] measured the field: scrape to the seed at points along rows.

[D] excluded 10 m headlands at each end of the 180 m plot and measured 3 rows x 40 points per
speed band. :func:`paper_sample` draws the rows and the points from the run's truth cells with a
seeded generator (rows without replacement, points evenly spaced with a random jitter, as a
person walking the row would place them); the suites compute GB/T 20865 statistics on it.
"""

from __future__ import annotations

import numpy as np


def paper_sample(distance_m: np.ndarray, depth_mm: np.ndarray, rng: np.random.Generator, *,
                 rows: int = 3, points: int = 40, headland_m: float = 10.0,
                 plot_length_m: float = 180.0) -> np.ndarray:
    """Depths (mm) at ``rows`` x ``points`` sampling points, shape (rows, points).

    ``distance_m`` (n,) and ``depth_mm`` (n, all_rows) are the truth cells of a run.
    """
    start, end = headland_m, plot_length_m - headland_m
    if end <= start:
        raise ValueError(f"headlands of {headland_m} m leave nothing of a {plot_length_m} m plot")
    if distance_m.size == 0 or distance_m[-1] < end:
        reached = float(distance_m[-1]) if distance_m.size else 0.0
        raise ValueError(f"the run covered {reached:.1f} m; sampling needs {end:.1f} m")
    if rows > depth_mm.shape[1]:
        raise ValueError(f"{rows} rows asked of a planter with {depth_mm.shape[1]}")
    chosen = rng.choice(depth_mm.shape[1], size=rows, replace=False)
    spacing = (end - start) / points
    out = np.empty((rows, points))
    for i, row in enumerate(sorted(chosen)):
        where = start + spacing * (np.arange(points) + rng.uniform(0.0, 1.0, points))
        idx = np.clip(np.searchsorted(distance_m, where), 0, distance_m.size - 1)
        out[i] = depth_mm[idx, row]
    return out
