"""What the fertilizer suites read from a run: traces, truth and the scenario's timing."""

from __future__ import annotations

import numpy as np

from hil.record import load_traces
from hil.rig import RunResult

#: every packaged bench/field scenario enables the controller at 3 s (the flow modules take
#: 2.2 s to measure their empty-pipe baseline first)
ENABLE_S = 3.0
#: the true flow carries flute pulsation and flute-to-flute fill noise: the suites judge it as
#: the scale and [F]'s own sensor see it, as mass per second (a centred 1 s mean)
TRUE_FLOW_FILTER = {"filter_kind": "mean", "filter_s": 1.0}
#: steady state of a bench step: the last 10 s of the 20 s after it. The true flow's ripple
#: (flute fill noise, ~1.3 % SD of the 1 s mean at 23 g/s, correlated over ~1 s) leaves a 5 s
#: mean uncertain by ~0.5 %, half the 1 % limit; over 10 s it is ~0.35 %
STEADY_WINDOW_S = 10.0


def row_mean(result: RunResult, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """Time and the mean over rows of the traces ``<prefix>_<row>_gps``."""
    arrays, _ = load_traces(result.out_dir / "traces.npz")
    rows = sorted(k for k in arrays if k.startswith(prefix + "_") and k.endswith("_gps"))
    if not rows:
        raise KeyError(f"{result.out_dir}/traces.npz has no {prefix}_<row>_gps traces")
    return arrays["time_s"], np.mean([arrays[k] for k in rows], axis=0)


def trace(result: RunResult, name: str) -> tuple[np.ndarray, np.ndarray]:
    arrays, _ = load_traces(result.out_dir / "traces.npz")
    return arrays["time_s"], arrays[name]


def delivered_and_target_g(result: RunResult) -> tuple[float, float]:
    """What the scale weighs (delivered plus still in the tubes at the end: it falls into the
    furrow/bucket after the run) and the target mass, all rows ([F] eq. 15's M2 and M1)."""
    truth = result.record["truth"]
    rows = len(truth["delivered_g"])
    delivered = float(truth["delivered_total_g"]) + float(sum(truth["in_transit_g"]))
    return delivered, float(truth["target_mass_per_row_g"]) * rows
