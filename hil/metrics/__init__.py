"""Metrics over recorded arrays: pure functions, numpy in, floats and frozen results out.

=============  ==========================================================================
``step``       step response: response/rise/settling time, overshoot, steady-state error
``accuracy``   [F] eq. 15 application accuracy θ from target flow and delivered mass
``tracking``   flow tracking error statistics (mean, MAE, RMS, max abs(e); also % of target)
``depth``      GB/T 20865-2007 sowing-depth statistics and [D]-style point sampling
``timing``     rig timing-health summary, and the worst-case merge over runs
=============  ==========================================================================

Every result is a frozen dataclass with ``to_dict()``; definitions are in each module's
docstring.
"""

from hil.metrics.accuracy import (
    AccuracyResult,
    RowAccuracy,
    accuracy_theta,
    delivered_mass,
    flow_accuracy,
    integrate_trace,
    target_mass,
)
from hil.metrics.depth import (
    DepthSample,
    DepthStats,
    depth_statistics,
    qualified_band,
    sample_depth,
)
from hil.metrics.step import (
    StepMetrics,
    judged_recovery,
    recovery_time,
    smooth,
    step_response,
)
from hil.metrics.timing import TimingSummary, merge_timing, timing_summary
from hil.metrics.tracking import TrackingStats, tracking_error
from hil.metrics.transients import TransientLag, transient_lag

__all__ = [
    "AccuracyResult",
    "DepthSample",
    "DepthStats",
    "RowAccuracy",
    "StepMetrics",
    "TimingSummary",
    "TrackingStats",
    "TransientLag",
    "accuracy_theta",
    "delivered_mass",
    "depth_statistics",
    "flow_accuracy",
    "integrate_trace",
    "judged_recovery",
    "merge_timing",
    "qualified_band",
    "recovery_time",
    "sample_depth",
    "smooth",
    "step_response",
    "target_mass",
    "timing_summary",
    "tracking_error",
    "transient_lag",
]
