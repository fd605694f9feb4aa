"""Step-response metrics of a *measured* signal, as [F] reports them for its flow steps.

Response, rise and settling time, overshoot and steady-state error (the suites report the
same for depth steps).

The setpoint steps at ``t0`` from ``y0`` to ``target``; ``step = target - y0`` (either sign).
Definitions (all times are measured from ``t0``; all bands are fractions of ``|step|``):

* **response time** — the time from the step until the signal enters the band
  ``|y - target| < band * |step|`` (default ``band = 0.05``, the ±5 % of hil/limits.py; a
  sample exactly on the edge counts as outside, as in step_info) and stays in it until the end
  of the window. It is ``nan`` (with a reason in ``notes``) when the signal is outside the
  band at the end, or has been inside it for less than ``min_hold_s`` before the end (a signal
  that has only just arrived has not shown that it stays).
* **settling time** — the same with ``settling_band`` (default 2 %, the textbook band). On a
  noisy signal a 2 % band may be meaningless (measured.md): read ``noise_sd`` before using it.
* **rise time** — from the first sample at or past ``y0 + 0.1 * step`` to the first sample at or
  past ``y0 + 0.9 * step`` (``rise_limits``).
* **overshoot** — ``max(0, peak beyond target) / |step| * 100`` %, the peak taken in the
  direction of the step (for a step down, the lowest value below the target).
* **steady-state error** — ``|mean(y over the last steady_window_s of the window) - target| /
  |target| * 100`` %, on the *raw* samples (the mean already averages the noise). Note the
  denominator is the target, not the step ([F]'s definition).
* **delay** — the time until the signal first leaves the ``band`` around ``y0`` in the
  direction of the step (a dead-time estimate; transport delay in [F]).

Where python-control is used, and where not
-------------------------------------------
``control.step_info(y, T=t, ...)`` works on measured data (measured.md). It is given the
*filtered* deviation ``y - y0`` from ``t0`` on, ``T = t - t0``, ``yfinal = step`` (so that its
rise limits and settling threshold are fractions of the step, not of ``y``) and
``SettlingTimeThreshold = band`` / ``settling_band``: its ``RiseTime``, ``SettlingTime`` and
``Overshoot`` are the rise time, response/settling time and overshoot above. Our own code does:

* the **filter** (below) — step_info has none, and on raw noisy data one sample out of band
  near the end makes the settling time jump to that sample, and one high sample is an
  overshoot;
* the **no-rise case** — step_info raises ``IndexError`` when the signal never reaches a rise
  limit, so then rise time is ``nan`` and the band test is done by :func:`_enter_and_stay`
  (the same rule as step_info's settling time);
* the **hold check** (``min_hold_s``), the **steady-state error**, the **delay** and the
  **peak**, which step_info does not define the way [F] does.

Filter
------
Default: a centred running **median** over ``filter_s = 0.2`` s (the sample count is
``round(filter_s / median dt)``, made odd; the window is truncated at the ends of the record).
A median of ``N`` samples removes any burst of up to ``(N - 1) // 2`` wild samples entirely
(10 at 100 Hz), leaves a monotone signal unchanged away from the ends of the record (a
first-order response, and a zero-order-held staircase, keep their exact crossing times) and
divides white noise by about ``1.25 / sqrt(N)``.
Its price: it trims a sharp peak by about ``|y''| * (filter_s / 4)**2 / 2`` (a second-order
response with 25 % overshoot reads 0.3 points low at ``wn = 3 rad/s``, 1.3 points at 6 rad/s),
and leftover noise still lifts the peak: with white noise of SD ``sd`` (% of the step) on an
11 s record at 100 Hz, a response without overshoot reads an overshoot of 0.6-0.8 ``sd``
typically and up to ~1.1 ``sd`` (20 seeds). Use ``filter_s`` and ``noise_sd`` to judge: an
overshoot under ~``1.5 sd`` is not distinguishable from noise.
``filter_kind="mean"`` (a centred moving average of the same length) suits periodic ripple such as
flute pulsation (choose ``filter_s`` = a whole number of ripple periods); ``filter_kind="none"``
uses raw samples. A mean is judged only where its window is whole: the last half window of the
record is left out of the band, rise and peak tests (there the truncated window no longer spans
whole ripple periods and lets the ripple through; a response must still hold its band up to
half a window before the end).

Resolution: times are sample times (the first sample inside, as step_info reports), so they are
exact to one sample period; no interpolation, which would be wrong for held signals.
Sampling is assumed near-uniform (the filter length comes from the median sample period).
Non-finite samples of ``y`` are dropped (and counted in ``notes``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import control
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from hil.metrics._common import DictMixin, as_time

__all__ = ["StepMetrics", "judged_recovery", "recovery_time", "smooth", "step_response"]

FilterKind = Literal["median", "mean", "none"]


@dataclass(frozen=True)
class StepMetrics(DictMixin):
    """Step-response metrics (see the module docstring for the definitions)."""

    t0_s: float
    y0: float
    target: float
    step: float
    band: float
    response_time_s: float
    settling_band: float
    settling_time_s: float
    rise_time_s: float
    overshoot_pct: float
    peak_value: float
    peak_time_s: float
    delay_s: float
    steady_state_value: float
    steady_state_error_pct: float
    steady_window_s: float
    #: robust estimate of the white-noise SD of the raw signal in the steady window
    #: (1.4826 * MAD of first differences / sqrt 2; ~0 for a held signal)
    noise_sd: float
    filter: str
    filter_samples: int
    #: why a value is nan, and anything else worth knowing about the computation
    notes: tuple[str, ...] = ()


def smooth(y: np.ndarray, samples: int, kind: FilterKind = "median") -> np.ndarray:
    """Centred running median or mean of ``samples`` (odd) points.

    Near the ends of the record the window is truncated to the samples that exist (so the last
    output is the median of the last ``samples // 2 + 1`` samples): padding with the end value
    instead would let one noisy end sample fill half the window.
    """
    y = np.asarray(y, dtype=float)
    if kind == "none" or samples <= 1 or y.size < 2:
        return y.copy()
    if kind not in ("median", "mean"):
        raise ValueError(f"unknown filter {kind!r} (median, mean, none)")
    if samples % 2 == 0:
        raise ValueError(f"filter length must be odd, got {samples}")
    reduce = np.median if kind == "median" else np.mean
    half = samples // 2
    out = np.empty_like(y)
    if y.size > 2 * half:
        out[half:y.size - half] = reduce(sliding_window_view(y, samples), axis=1)
    for i in (*range(min(half, y.size)), *range(max(half, y.size - half), y.size)):
        out[i] = reduce(y[max(0, i - half):i + half + 1])
    return out


def _filter_length(t: np.ndarray, filter_s: float) -> int:
    if t.size < 2 or filter_s <= 0:
        return 1
    n = round(filter_s / float(np.median(np.diff(t))))
    return max(1, n if n % 2 else n + 1)


def _whole_windows(t: np.ndarray, samples: int, kind: FilterKind) -> np.ndarray:
    """Mark the samples a filter of ``samples`` points is judged at.

    All of them, except for a mean the last ``samples // 2``, whose centred window the end of
    the record truncates.
    """
    keep = np.ones(t.shape, dtype=bool)
    if kind == "mean" and samples > 1:
        keep[max(0, t.size - samples // 2):] = False
    return keep


def _enter_and_stay(ts: np.ndarray, d: np.ndarray, step: float, band: float) -> float:
    """First sample time from which ``abs(d/step - 1) < band`` holds to the end (nan: never).

    step_info's rule: a sample exactly on the band edge counts as outside.
    """
    outside = np.nonzero(np.abs(d / step - 1.0) >= band)[0]
    settled = 0 if outside.size == 0 else int(outside[-1]) + 1
    return float(ts[settled]) if settled < ts.size else math.nan


def step_response(t: np.ndarray, y: np.ndarray, *, t0: float, target: float,
                  y0: float | None = None, band: float = 0.05, settling_band: float = 0.02,
                  rise_limits: tuple[float, float] = (0.1, 0.9),
                  steady_window_s: float = 5.0, min_hold_s: float = 1.0,
                  filter_kind: FilterKind = "median", filter_s: float = 0.2,
                  t_end: float | None = None, pre_window_s: float = 1.0) -> StepMetrics:
    """Step-response metrics of ``y(t)`` for a setpoint step at ``t0`` to ``target``.

    The definitions are in the module docstring (:mod:`hil.metrics.step`). A signal that does not
    do what a metric needs gives nan for that metric and a reason in ``notes``.

    Parameters
    ----------
    t, y : numpy.ndarray
        The measured signal's samples, same shape; non-finite samples are dropped.
    t0 : float
        When the setpoint stepped.
    target : float
        The setpoint after the step.
    y0 : float, optional
        The level the step starts from; None takes the median of the raw samples in
        ``[t0 - pre_window_s, t0)`` (or the first sample at or after ``t0`` if there are none).
    band : float, optional
        The response-time band, a fraction of ``abs(step)`` in (0, 1).
    settling_band : float, optional
        The settling-time band, a fraction of ``abs(step)`` in (0, 1).
    rise_limits : tuple of (float, float), optional
        The rise time's start and end, fractions of the step, ``0 <= low < high <= 1``.
    steady_window_s : float, optional
        The steady-state error is the mean over this last part of the window.
    min_hold_s : float, optional
        How long the signal must have been in the band before the end for a response or
        settling time.
    filter_kind : {"median", "mean", "none"}, optional
        The smoothing applied before the band, rise and peak tests.
    filter_s : float, optional
        The smoothing window, in s.
    t_end : float, optional
        The end of the window (default: the last sample).
    pre_window_s : float, optional
        The stretch before ``t0`` that ``y0`` is taken from.

    Returns
    -------
    StepMetrics
        The metrics, with the notes.

    Raises
    ------
    ValueError
        Mismatched shapes, bands or rise limits out of range, fewer than 2 samples in the window,
        or a zero step.
    """
    t = as_time(t)
    y = np.asarray(y, dtype=float)
    if y.shape != t.shape:
        raise ValueError(f"y has shape {y.shape}, t has {t.shape}")
    if not 0 < band < 1 or not 0 < settling_band < 1:
        raise ValueError(f"bands must be fractions of the step in (0, 1): {band}, {settling_band}")
    lo_lim, hi_lim = rise_limits
    if not 0 <= lo_lim < hi_lim <= 1:
        raise ValueError(f"rise limits must satisfy 0 <= low < high <= 1: {rise_limits}")
    notes: list[str] = []

    finite = np.isfinite(y)
    if not finite.all():
        notes.append(f"{int((~finite).sum())} non-finite samples dropped")
        t, y = t[finite], y[finite]
    end = float(t[-1]) if t_end is None else float(t_end)
    keep = t <= end
    t, y = t[keep], y[keep]
    after = t >= t0
    if int(after.sum()) < 2 or end <= t0:
        raise ValueError(f"need at least 2 samples in the window [{t0}, {end}] s")

    if y0 is None:
        before = (t >= t0 - pre_window_s) & (t < t0)
        if before.any():
            y0 = float(np.median(y[before]))
        else:
            y0 = float(y[after][0])
            notes.append("y0 taken from the first sample at the step (no samples before it)")
    y0 = float(y0)
    step = float(target) - y0
    if step == 0:
        raise ValueError(f"zero step: y0 = target = {target}")
    sgn = 1.0 if step > 0 else -1.0

    n_filt = _filter_length(t, filter_s) if filter_kind != "none" else 1
    yf = smooth(y, n_filt, filter_kind)
    if filter_kind != "none" and n_filt < 3:
        notes.append(f"filter inactive: {filter_s} s is under 3 samples")
    whole = _whole_windows(t, n_filt, filter_kind)
    judged = after & whole
    if int(judged.sum()) < 2:
        raise ValueError(f"need at least 2 samples with a whole {filter_s} s filter window "
                         f"in [{t0}, {end}] s")

    ts = t[judged] - t0
    d = yf[judged] - y0                 # filtered deviation from y0: what step_info is given
    y_raw = y[after]
    duration = float(ts[-1])

    # -- rise, response, settling, overshoot: step_info where it applies ---------------------
    reaches_high = bool(np.any(sgn * d >= sgn * hi_lim * step))
    if reaches_high:
        info = control.step_info(d, T=ts, yfinal=step, SettlingTimeThreshold=band,
                                 RiseTimeLimits=rise_limits)
        rise = float(info["RiseTime"])
        response = float(info["SettlingTime"])
        overshoot = float(info["Overshoot"])
        settling = float(control.step_info(d, T=ts, yfinal=step,
                                           SettlingTimeThreshold=settling_band,
                                           RiseTimeLimits=rise_limits)["SettlingTime"])
    else:
        # step_info would raise IndexError here (it looks up the first sample past the limit)
        rise = math.nan
        notes.append(f"rise time: the signal never reached {hi_lim:.0%} of the step "
                     f"(closest {100 * float(np.max(sgn * d)) / abs(step):.1f} %)")
        response = _enter_and_stay(ts, d, step, band)
        settling = _enter_and_stay(ts, d, step, settling_band)
        overshoot = 0.0

    def _held(value: float, which: str, width: float) -> float:
        if math.isnan(value):
            last = 100 * abs(float(d[-1]) / step - 1.0)
            notes.append(f"{which}: never entered and stayed in the ±{width:.0%} band "
                         f"(filtered signal {last:.1f} % of the step from the target at the end)")
            return math.nan
        if duration - value < min_hold_s:
            notes.append(f"{which}: in the ±{width:.0%} band only for the last "
                         f"{duration - value:.3g} s (< min_hold_s = {min_hold_s} s)")
            return math.nan
        return value

    response = _held(response, "response time", band)
    settling = _held(settling, "settling time", settling_band)

    # -- our own: peak, delay, steady state, noise -------------------------------------------
    i_peak = int(np.argmax(sgn * d))
    peak_value = float(yf[judged][i_peak])
    peak_time = float(ts[i_peak])

    left = np.nonzero(sgn * d > band * abs(step))[0]
    delay = float(ts[left[0]]) if left.size else math.nan
    if not left.size:
        notes.append(f"delay: the signal never left the ±{band:.0%} band around y0")

    start_ss = end - steady_window_s
    in_ss = t[after] >= start_ss       # the raw samples: the steady window runs to the end
    if start_ss < t0:
        ss_value = ss_err = math.nan
        notes.append(f"steady-state error: window of {end - t0:.3g} s after the step is shorter "
                     f"than steady_window_s = {steady_window_s} s")
    else:
        ss_value = float(np.mean(y_raw[in_ss]))
        if target == 0:
            ss_err = math.nan
            notes.append("steady-state error: undefined for a zero target (% of target)")
        else:
            ss_err = abs(ss_value - target) / abs(target) * 100.0
    tail = y_raw[in_ss] if in_ss.sum() >= 3 else y_raw
    diffs = np.diff(tail)
    noise_sd = float(1.4826 * np.median(np.abs(diffs - np.median(diffs))) / math.sqrt(2.0)) \
        if diffs.size else 0.0
    filtered_sd = noise_sd * (1.25 / math.sqrt(n_filt) if filter_kind == "median" and n_filt > 1
                              else 1.0 / math.sqrt(n_filt))
    if 3.0 * filtered_sd > band * abs(step):
        notes.append(f"the ±{band:.0%} band ({band * abs(step):.3g}) is under 3 SD of the "
                     f"filtered noise ({filtered_sd:.3g}): widen the band or the filter")

    return StepMetrics(
        t0_s=float(t0), y0=y0, target=float(target), step=step, band=band,
        response_time_s=response, settling_band=settling_band, settling_time_s=settling,
        rise_time_s=rise, overshoot_pct=overshoot, peak_value=peak_value,
        peak_time_s=peak_time, delay_s=delay, steady_state_value=ss_value,
        steady_state_error_pct=ss_err, steady_window_s=steady_window_s, noise_sd=noise_sd,
        filter=filter_kind, filter_samples=n_filt, notes=tuple(notes))


def recovery_time(t: np.ndarray, y: np.ndarray, *, t0: float, target: float,
                  band: float = 0.05, min_hold_s: float = 1.0,
                  filter_kind: FilterKind = "mean", filter_s: float = 1.0) -> float:
    """Time from a disturbance at ``t0`` until the filtered signal is back near ``target`` to stay.

    A disturbance is a DUT restart or a fault cleared. "Near" is within ``band`` of ``target``
    (a fraction of the target, not of a step: there is no step), up to the end of the record.

    Parameters
    ----------
    t, y : numpy.ndarray
        The signal's samples, same shape.
    t0 : float
        When the disturbance happened.
    target : float
        The level the signal should return to, not 0.
    band : float, optional
        The band as a fraction of ``target``, in (0, 1).
    min_hold_s : float, optional
        How long it must have been back before the end of the record to count.
    filter_kind : {"mean", "median", "none"}, optional
        The smoothing applied before the band is checked.
    filter_s : float, optional
        The smoothing window, in seconds.

    Returns
    -------
    float
        Seconds after ``t0``: 0 when it never left, nan when it is out of the band at the end or
        has been back for less than ``min_hold_s``.

    Raises
    ------
    ValueError
        Mismatched shapes, a zero target, a band outside (0, 1), or fewer than 2 samples after
        ``t0``.
    """
    t = as_time(t)
    y = np.asarray(y, dtype=float)
    if y.shape != t.shape:
        raise ValueError(f"y has shape {y.shape}, t has {t.shape}")
    if target == 0 or not 0 < band < 1:
        raise ValueError(f"need a non-zero target and a band in (0, 1): {target}, {band}")
    n = _filter_length(t, filter_s) if filter_kind != "none" else 1
    yf = smooth(y, n, filter_kind)
    after = (t >= t0) & _whole_windows(t, n, filter_kind)
    if int(after.sum()) < 2:
        raise ValueError(f"need at least 2 samples after t0 = {t0}")
    ts = t[after] - t0
    back = _enter_and_stay(ts, yf[after], float(target), band)
    if math.isnan(back) or float(ts[-1]) - back < min_hold_s:
        return math.nan
    return back


def judged_recovery(value: float, t: np.ndarray, *, t0: float, band: float = 0.05,
                    min_hold_s: float = 1.0) -> tuple[float, str]:
    """A recovery time made fit to judge: ``(value, "")`` when it was timed, else a bound and why.

    The bound is the length of the record after ``t0`` (a lower bound of the recovery time: a
    limit below it fails); the reason reads "never re-entered the ±5 % band within N s". A
    signal that never comes back has failed its recovery; it is not a measurement that could
    not be made (that is for a run that ended early, which the suites mark apart).

    Parameters
    ----------
    value : float
        What :func:`recovery_time` returned.
    t : numpy.ndarray
        The record's sample times.
    t0 : float
        When the disturbance happened.
    band, min_hold_s : float, optional
        As given to :func:`recovery_time` (named in the reason).

    Returns
    -------
    tuple of (float, str)
        The value to judge and the note (empty when it was timed).
    """
    if not math.isnan(value):
        return value, ""
    t = np.asarray(t, dtype=float)
    span = float(t[-1] - t0) if t.size else 0.0
    return span, (f"never re-entered the ±{band:.0%} band (and stayed {min_hold_s:g} s) "
                  f"within {span:.1f} s: the value is that bound")
