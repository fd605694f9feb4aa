"""Flow tracking error statistics between a target trace and a measured (or true) trace.

The error is ``e = measured - target`` (positive: over-delivery), evaluated at the measured
samples inside the window ``[t_start, t_end]`` (the target is interpolated there if it has its
own time base). Statistics are plain sample statistics (uniform sampling assumed):

* ``mean_error``  = mean(e)            (bias; signed)
* ``mae``         = mean(|e|)
* ``rms``         = sqrt(mean(e²))
* ``max_abs``     = max |e| (and the time of it)

each also as a percentage of the **mean target over the window** (``*_pct = stat / |mean
target| · 100``), not per sample: a per-sample ratio blows up where the target is near zero
(start-up, headland turns). Non-finite measured samples (sensor dropouts) are left out and
counted in ``dropped``. Units are the traces' (g/s for flow; ``unit`` only labels them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from hil.metrics._common import DictMixin, as_time, sample_trace

__all__ = ["TrackingStats", "tracking_error"]


@dataclass(frozen=True)
class TrackingStats(DictMixin):
    """Tracking error statistics over a window (see the module docstring)."""

    t_start_s: float
    t_end_s: float
    n: int
    dropped: int
    unit: str
    mean_target: float
    mean_error: float
    mae: float
    rms: float
    max_abs: float
    max_abs_time_s: float
    mean_error_pct: float
    mae_pct: float
    rms_pct: float
    max_abs_pct: float


def tracking_error(t: np.ndarray, target: np.ndarray, measured: np.ndarray, *,
                   t_start: float | None = None, t_end: float | None = None,
                   t_target: np.ndarray | None = None,
                   interp: Literal["linear", "previous"] = "linear",
                   unit: str = "g/s") -> TrackingStats:
    """Error statistics of ``measured(t)`` against ``target`` over ``[t_start, t_end]``.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times of ``measured``.
    target : numpy.ndarray
        The target, sampled at ``t`` unless ``t_target`` is given.
    measured : numpy.ndarray
        The measured signal, sampled at ``t``.
    t_start, t_end : float, optional
        The window (default: the whole of ``t``); it must hold at least one finite sample.
    t_target : numpy.ndarray, optional
        Sample times of ``target``; it is then interpolated at ``t``.
    interp : {"linear", "previous"}, optional
        How ``target`` is interpolated (``"previous"`` for a setpoint log held between changes).
    unit : str, optional
        The traces' unit; it only labels the result.

    Returns
    -------
    TrackingStats
        The statistics over the window's finite samples (the others counted in ``dropped``).

    Raises
    ------
    ValueError
        Mismatched shapes, or no finite samples in the window.
    """
    t = as_time(t)
    meas = np.asarray(measured, dtype=float)
    if meas.shape != t.shape:
        raise ValueError(f"measured has shape {meas.shape}, t has {t.shape}")
    lo = float(t[0]) if t_start is None else float(t_start)
    hi = float(t[-1]) if t_end is None else float(t_end)
    win = (t >= lo) & (t <= hi)
    tw, mw = t[win], meas[win]
    if t_target is None:
        tgt = np.asarray(target, dtype=float)
        if tgt.shape != t.shape:
            raise ValueError(f"target has shape {tgt.shape}, t has {t.shape}")
        tw_target = tgt[win]
    else:
        tt = as_time(t_target, "t_target")
        tgt = np.asarray(target, dtype=float)
        if tgt.shape != tt.shape:
            raise ValueError(f"target has shape {tgt.shape}, t_target has {tt.shape}")
        tw_target = sample_trace(tt, tgt, tw, interp)
    ok = np.isfinite(mw) & np.isfinite(tw_target)
    if not ok.any():
        raise ValueError(f"no finite samples in the window [{lo}, {hi}] s")
    e = mw[ok] - tw_target[ok]
    mean_target = float(np.mean(tw_target[ok]))
    i_max = int(np.argmax(np.abs(e)))
    stats = {"mean_error": float(np.mean(e)), "mae": float(np.mean(np.abs(e))),
             "rms": float(np.sqrt(np.mean(e * e))), "max_abs": float(np.abs(e[i_max]))}

    def pct(v: float) -> float:
        return v / abs(mean_target) * 100.0 if mean_target != 0 else math.nan

    return TrackingStats(
        t_start_s=lo, t_end_s=hi, n=int(ok.sum()), dropped=int((~ok).sum()), unit=unit,
        mean_target=mean_target, **stats, max_abs_time_s=float(tw[ok][i_max]),
        mean_error_pct=pct(stats["mean_error"]), mae_pct=pct(stats["mae"]),
        rms_pct=pct(stats["rms"]), max_abs_pct=pct(stats["max_abs"]))
