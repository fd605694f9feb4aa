"""What the sowing-depth suites read from a run."""

from __future__ import annotations

import numpy as np

from hil.rig import RunResult

#: [D] excludes 10 m headlands at each end of the 180 m plot
HEADLAND_M = 10.0
PLOT_M = 180.0


def trace(result: RunResult, name: str) -> tuple[np.ndarray, np.ndarray]:
    arrays, _ = result.traces()
    return arrays["time_s"], arrays[name]


def plot_truth(result: RunResult) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m) and true seed depths (cells x rows) inside the plot, headlands excluded."""
    truth = result.truth_arrays()
    x = truth["distance_m"]
    depth = truth["depth_mm"]
    inside = (x >= HEADLAND_M) & (x <= PLOT_M - HEADLAND_M)
    return x[inside], depth[inside]
