"""Fertilizer application accuracy, [F] eq. 15.

    θ = (1 - |M1 - M2| / M1) · 100 %

with ``M1`` the target mass and ``M2`` the true (weighed) mass over the same window. θ is
symmetric in the sign of the error (delivering 2 % too much or too little both give 98 %), so
results also carry the signed ``bias_pct = (M2 - M1) / M1 · 100``.

``M1`` comes from the target-flow trace (g/s) integrated over the window ([F]: 50 s bench runs,
60 s field runs; eq. 16: 66.7 g/s for 60 s → 4,000 g); ``M2`` from the cumulative delivered grams
(the truth a scale would weigh) as ``cum(t_end) - cum(t_start)``, linearly interpolated (a
cumulative mass is continuous). Per row and total: the total θ is computed from the summed
masses — not the mean of the row θ's, since row errors of opposite sign cancel in the weighed
total — and the row θ's are reported beside it (``mean_row_theta_pct``, ``min_row_theta_pct``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from hil.metrics._common import DictMixin, as_time, sample_trace

__all__ = ["AccuracyResult", "RowAccuracy", "accuracy_theta", "delivered_mass",
           "flow_accuracy", "integrate_trace", "target_mass"]

Interp = Literal["linear", "previous"]


def accuracy_theta(target_mass_g: float, true_mass_g: float) -> float:
    """``θ = (1 - |M1 - M2| / M1) · 100 %``, [F] eq. 15 (M1 target, M2 true mass; M1 > 0)."""
    m1, m2 = float(target_mass_g), float(true_mass_g)
    if not m1 > 0 or not math.isfinite(m1):
        raise ValueError(f"target mass must be positive and finite, got {target_mass_g}")
    return (1.0 - abs(m1 - m2) / m1) * 100.0


def integrate_trace(t: np.ndarray, y: np.ndarray, t_start: float, t_end: float, *,
                    interp: Interp = "linear") -> float | np.ndarray:
    """∫ y dt over ``[t_start, t_end]`` (inside the trace); ``y`` of shape (n,) or (n, k).

    ``interp="linear"`` is the trapezoid rule over the samples, with the window edges
    interpolated (right for a sampled continuous flow, e.g. ``Q = 60·v`` following the speed);
    ``"previous"`` integrates the trace held from each sample to the next (right for a setpoint
    logged when it changes). On a 100 Hz record of a step setpoint the two differ by
    ``dt/2`` times the step per step change.
    """
    t = as_time(t)
    y = np.asarray(y, dtype=float)
    if y.shape[:1] != t.shape or y.ndim > 2:
        raise ValueError(f"trace has shape {y.shape}; expected ({t.size},) or ({t.size}, k)")
    if not t_end > t_start:
        raise ValueError(f"empty window [{t_start}, {t_end}]")
    inside = (t > t_start) & (t < t_end)
    x = np.concatenate([[t_start], t[inside], [t_end]])
    v = sample_trace(t, y, x, interp)
    dx = np.diff(x)
    if interp == "previous":
        total = np.tensordot(dx, v[:-1], axes=(0, 0))
    else:
        total = np.tensordot(dx, 0.5 * (v[1:] + v[:-1]), axes=(0, 0))
    return float(total) if np.ndim(total) == 0 else np.asarray(total)


def target_mass(t: np.ndarray, target_flow_gps: np.ndarray, t_start: float, t_end: float, *,
                interp: Interp = "linear") -> float | np.ndarray:
    """M1 (g): the target flow (g/s; (n,) total or (n, rows)) integrated over the window."""
    return integrate_trace(t, target_flow_gps, t_start, t_end, interp=interp)


def delivered_mass(t: np.ndarray, cumulative_g: np.ndarray, t_start: float,
                   t_end: float) -> float | np.ndarray:
    """M2 (g): ``cum(t_end) - cum(t_start)`` of a cumulative-grams truth trace.

    The trace is (n,) or (n, rows), linearly interpolated at the window edges.

    Raises
    ------
    ValueError
        The trace's shape does not match ``t``, or the window is empty.
    """
    t = as_time(t)
    c = np.asarray(cumulative_g, dtype=float)
    if c.shape[:1] != t.shape or c.ndim > 2:
        raise ValueError(f"cumulative trace has shape {c.shape}; expected ({t.size},) or "
                         f"({t.size}, rows)")
    if not t_end > t_start:
        raise ValueError(f"empty window [{t_start}, {t_end}]")
    ends = sample_trace(t, c, np.array([t_start, t_end]), "linear")
    out = ends[1] - ends[0]
    return float(out) if np.ndim(out) == 0 else np.asarray(out)


@dataclass(frozen=True)
class RowAccuracy(DictMixin):
    """θ of one row over a window (one entry of :attr:`AccuracyResult.rows`).

    Parameters
    ----------
    row : int
        The row's index, from 0.
    target_mass_g : float
        M1: the row's target mass over the window.
    delivered_mass_g : float
        M2: the row's delivered (true) mass over the window.
    theta_pct : float
        θ, [F] eq. 15.
    bias_pct : float
        ``(M2 - M1) / M1 · 100``.
    """

    row: int
    target_mass_g: float
    delivered_mass_g: float
    theta_pct: float
    bias_pct: float


@dataclass(frozen=True)
class AccuracyResult(DictMixin):
    """θ over a window, total (from summed masses) and per row."""

    t_start_s: float
    t_end_s: float
    target_mass_g: float
    delivered_mass_g: float
    theta_pct: float
    bias_pct: float
    rows: tuple[RowAccuracy, ...] = ()
    mean_row_theta_pct: float = math.nan
    min_row_theta_pct: float = math.nan


def _bias(m1: float, m2: float) -> float:
    return (m2 - m1) / m1 * 100.0


def flow_accuracy(t: np.ndarray, target_flow_gps: np.ndarray, cumulative_g: np.ndarray,
                  t_start: float, t_end: float, *, t_truth: np.ndarray | None = None,
                  interp: Interp = "linear",
                  row_weights: np.ndarray | None = None) -> AccuracyResult:
    """[F] eq. 15 over ``[t_start, t_end]``, per row and total.

    The total θ is computed from the summed masses; with a 1-D truth only the total is reported.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times of the target flow, in s.
    target_flow_gps : numpy.ndarray
        (n,) total target flow, or (n, rows) per row, in g/s, sampled at ``t``.
    cumulative_g : numpy.ndarray
        (m,) total or (m, rows) per-row delivered grams at ``t_truth``.
    t_start, t_end : float
        The window, in s.
    t_truth : numpy.ndarray, optional
        Sample times of ``cumulative_g`` (default ``t``).
    interp : {"linear", "previous"}, optional
        How the target flow is integrated (:func:`integrate_trace`).
    row_weights : numpy.ndarray, optional
        How a total target is split over the rows (default equal: [F]'s four identical rows).

    Returns
    -------
    AccuracyResult
        θ and bias, total and per row, with the masses.

    Raises
    ------
    ValueError
        Shapes that do not match, an empty window, bad row weights, or per-row targets with a
        total truth.
    """
    t_truth = t if t_truth is None else t_truth
    m1 = target_mass(t, target_flow_gps, t_start, t_end, interp=interp)
    m2 = delivered_mass(t_truth, cumulative_g, t_start, t_end)
    rows: tuple[RowAccuracy, ...] = ()
    if np.ndim(m2) == 1:
        n_rows = int(np.size(m2))
        if np.ndim(m1) == 0:
            w = np.ones(n_rows) if row_weights is None else np.asarray(row_weights, float)
            if w.shape != (n_rows,) or np.any(w < 0) or not w.sum() > 0:
                raise ValueError(f"row_weights must be {n_rows} non-negative weights")
            m1 = float(m1) * w / w.sum()
        elif np.size(m1) != n_rows:
            raise ValueError(f"{np.size(m1)} target rows but {n_rows} truth rows")
        rows = tuple(RowAccuracy(row=i, target_mass_g=float(a), delivered_mass_g=float(b),
                                 theta_pct=accuracy_theta(a, b), bias_pct=_bias(a, b))
                     for i, (a, b) in enumerate(zip(m1, m2, strict=True)))
    elif np.ndim(m1) == 1:
        raise ValueError("per-row targets need per-row truth (cumulative_g of shape (n, rows))")
    total1, total2 = float(np.sum(m1)), float(np.sum(m2))
    row_thetas = [r.theta_pct for r in rows]
    return AccuracyResult(
        t_start_s=float(t_start), t_end_s=float(t_end), target_mass_g=total1,
        delivered_mass_g=total2, theta_pct=accuracy_theta(total1, total2),
        bias_pct=_bias(total1, total2), rows=rows,
        mean_row_theta_pct=float(np.mean(row_thetas)) if rows else math.nan,
        min_row_theta_pct=float(np.min(row_thetas)) if rows else math.nan)
