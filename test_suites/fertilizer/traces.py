"""What the fertilizer suites read from a run: traces, truth and the scenario's timing."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil.rig import RunResult
from plant_emulators.fertilizer.config import load_rig_config

#: every packaged bench/field scenario enables the controller at 3 s (the flow modules take
#: 2.2 s to measure their empty-pipe baseline first)
ENABLE_S = 3.0
#: the true flow carries flute pulsation and flute-to-flute fill noise: the suites judge it as
#: mass per whole number of flute periods (see :func:`flow_filter`), about one second
FLOW_WINDOW_S = 1.0
#: steady state of a bench step: the last 10 s of the 20 s after it. The true flow's ripple
#: (flute fill noise, ~1.3 % SD of the 1 s mean at 23 g/s, correlated over ~1 s) leaves a 5 s
#: mean uncertain by ~0.5 %, half the 1 % limit; over 10 s it is ~0.35 %
STEADY_WINDOW_S = 10.0


def row_mean(result: RunResult, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """Time and the mean over rows of the traces ``<prefix>_<row>_gps``."""
    arrays, _ = result.traces()
    rows = sorted(k for k in arrays if k.startswith(prefix + "_") and k.endswith("_gps"))
    if not rows:
        raise KeyError(f"{result.out_dir}/traces.npz has no {prefix}_<row>_gps traces")
    return arrays["time_s"], np.mean([arrays[k] for k in rows], axis=0)


def trace(result: RunResult, name: str) -> tuple[np.ndarray, np.ndarray]:
    arrays, _ = result.traces()
    return arrays["time_s"], arrays[name]


def delivered_and_target_g(result: RunResult) -> tuple[float, float]:
    """What the scale weighs (delivered plus still in the tubes at the end: it falls into the
    furrow/bucket after the run) and the target mass, all rows ([F] eq. 15's M2 and M1)."""
    truth = result.record["truth"]
    rows = len(truth["delivered_g"])
    delivered = float(truth["delivered_total_g"]) + float(sum(truth["in_transit_g"]))
    return delivered, float(truth["target_mass_per_row_g"]) * rows


def transport_s(result: RunResult) -> float:
    """Meter to furrow in the run's rig: what is metered now lands this much later."""
    overrides = result.record.get("rig_config_overrides") or {}
    t = load_rig_config(overrides=overrides, source="the run's rig_config_overrides").transport
    return t.meter_to_sensor_delay_s + t.sensor_to_exit_delay_s


def flutes(result: RunResult) -> int:
    """The flutes per roller of the rig the run used (the packaged config and its overrides)."""
    overrides = result.record.get("rig_config_overrides") or {}
    config = load_rig_config(overrides=overrides, source="the run's rig_config_overrides")
    return config.meter.flutes


def flow_filter(result: RunResult, t0: float) -> dict[str, Any]:
    """How the suites smooth a flow trace after ``t0``: a centred mean over the whole number of
    flute periods that is the shortest to last at least ``FLOW_WINDOW_S``.

    A fluted roller discharges in pulses at ``flutes x shaft speed`` (12 x 12.5 r/min = 2.5 Hz
    at 23 g/s). A 1 s mean keeps |sinc(f x 1 s)| of that pulsation: 13 % at 2.5 Hz, the worst
    case, which is a ripple of the meter no controller can act on (it is far beyond any flow
    loop's bandwidth: the flow modules report 1 s windows) and which a test that reads it as
    overshoot or as leaving the band judges the meter, not the controller. A mean over whole
    flute periods holds every flute's charge exactly once per period: the pulsation's
    harmonics cancel, the flute-to-flute fill noise and everything the controller does stay.
    The period comes from the median shaft speed after ``t0`` (the traced shaft, which the rig
    knows); at standstill the plain ``FLOW_WINDOW_S`` mean is used.
    """
    t, shaft = trace(result, "shaft_speed_rpm")
    turning = shaft[(t >= t0) & (shaft > 0.5)]
    if turning.size == 0:
        return {"filter_kind": "mean", "filter_s": FLOW_WINDOW_S}
    period_s = 60.0 / (flutes(result) * float(np.median(turning)))
    periods = max(1, math.ceil(FLOW_WINDOW_S / period_s - 1e-9))
    return {"filter_kind": "mean", "filter_s": periods * period_s}
