"""Sowing-depth statistics per GB/T 20865-2007, sampled the way [D] sampled its field.

**Qualified band.** A depth ``h`` is qualified when ``target - tol <= h <= target + tol``
(edges inclusive) with ``tol = 10 mm`` for a target of 30 mm or more and ``tol = 5 mm`` below
30 mm (the GB/T 20865-2007 rule as [D] applies it: 30 mm → 20-40 mm).

**Statistics** over all ``n`` samples (e.g. [D]'s 3 rows x 40 points = 120):

* mean ``h̄ = Σh / n``
* pass rate ``= n_qualified / n · 100 %``
* SD ``s = sqrt(Σ(h - h̄)² / (n - 1))`` (sample SD, ddof = 1)
* CV ``= s / h̄ · 100 %``

and the same mean, SD and CV over the qualified samples only (``inlier_*``), reported
separately: papers.md reads [D] Table 3 as a ~1 mm spread (CV ~3 %) plus an outlier process
(pass rate ~92 %), and the two cannot both be seen in one SD.

**Sampling** (:func:`sample_depth`): ``points`` per row equally spaced along the travelled
distance with ``headland_m`` excluded at each end — the centres of ``points`` equal segments of
``[start + headland, end - headland]`` — each taking the depth of the nearest truth cell.
``jitter`` (0-1, a fraction of the spacing) moves each point uniformly within its own segment
with a seeded generator, as a person placing points along a row would; ``jitter = 0`` is fully
deterministic. (``plant_emulators.sowing_depth.sampling.paper_sample`` is the emulator-side
sampler that also picks the rows at random; this one takes the rows it is given.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hil.metrics._common import DictMixin, as_time

__all__ = ["DepthSample", "DepthStats", "depth_statistics", "qualified_band", "sample_depth"]


def qualified_band(target_mm: float) -> tuple[float, float]:
    """GB/T 20865-2007 qualified depth band (mm): ±10 mm for targets >= 30 mm, else ±5 mm."""
    if not target_mm > 0:
        raise ValueError(f"target depth must be positive, got {target_mm}")
    tol = 10.0 if target_mm >= 30.0 else 5.0
    return (target_mm - tol, target_mm + tol)


@dataclass(frozen=True)
class DepthStats(DictMixin):
    """GB/T 20865 depth statistics, overall and over the qualified (inlier) samples."""

    target_mm: float
    band_low_mm: float
    band_high_mm: float
    n: int
    n_qualified: int
    n_below: int
    n_above: int
    pass_rate_pct: float
    mean_mm: float
    sd_mm: float
    cv_pct: float
    inlier_mean_mm: float
    inlier_sd_mm: float
    inlier_cv_pct: float
    #: per row (when the samples are 2-D, rows first): mean and pass rate
    row_mean_mm: tuple[float, ...] = ()
    row_pass_rate_pct: tuple[float, ...] = ()


def _mean_sd_cv(x: np.ndarray) -> tuple[float, float, float]:
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(np.mean(x))
    sd = float(np.std(x, ddof=1)) if x.size > 1 else math.nan
    cv = sd / mean * 100.0 if mean != 0 else math.nan
    return mean, sd, cv


def depth_statistics(samples_mm: np.ndarray, target_mm: float = 30.0, *,
                     band_mm: tuple[float, float] | None = None) -> DepthStats:
    """Statistics of depth samples (any shape; 2-D is read as rows x points).

    Parameters
    ----------
    samples_mm : numpy.ndarray
        The sampled depths, all finite (a missing measurement point must be dealt with by the
        caller).
    target_mm : float, optional
        The target depth.
    band_mm : tuple of (float, float), optional
        Overrides the GB/T 20865 qualified band (inclusive edges).

    Returns
    -------
    DepthStats
        Overall statistics and those over the qualified samples.

    Raises
    ------
    ValueError
        No samples, non-finite samples, or an empty band.
    """
    x = np.asarray(samples_mm, dtype=float)
    if x.size == 0:
        raise ValueError("no depth samples")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{int((~np.isfinite(x)).sum())} non-finite depth samples")
    lo, hi = qualified_band(target_mm) if band_mm is None else map(float, band_mm)
    if not hi > lo:
        raise ValueError(f"empty band {band_mm}")
    flat = x.ravel()
    ok = (flat >= lo) & (flat <= hi)
    mean, sd, cv = _mean_sd_cv(flat)
    imean, isd, icv = _mean_sd_cv(flat[ok])
    row_mean: tuple[float, ...] = ()
    row_pass: tuple[float, ...] = ()
    if x.ndim == 2:
        row_mean = tuple(float(v) for v in x.mean(axis=1))
        row_pass = tuple(float(v) for v in ((x >= lo) & (x <= hi)).mean(axis=1) * 100.0)
    return DepthStats(
        target_mm=float(target_mm), band_low_mm=lo, band_high_mm=hi, n=int(flat.size),
        n_qualified=int(ok.sum()), n_below=int((flat < lo).sum()),
        n_above=int((flat > hi).sum()), pass_rate_pct=float(ok.mean() * 100.0),
        mean_mm=mean, sd_mm=sd, cv_pct=cv, inlier_mean_mm=imean, inlier_sd_mm=isd,
        inlier_cv_pct=icv, row_mean_mm=row_mean, row_pass_rate_pct=row_pass)


@dataclass(frozen=True, eq=False)
class DepthSample(DictMixin):
    """Sampled points: ``positions_m`` and ``depth_mm`` of shape (rows, points)."""

    rows: tuple[int, ...]
    positions_m: np.ndarray
    depth_mm: np.ndarray


def sample_depth(positions_m: np.ndarray, depth_mm: np.ndarray, *, points: int = 40,
                 headland_m: float = 10.0, rows: Sequence[int] | None = None,
                 jitter: float = 0.0, seed: int | np.random.Generator | None = None,
                 ) -> DepthSample:
    """Sample ``points`` depths per row from a truth array ``depth_mm[rows, cells]``.

    The sampled stretch is ``[positions_m[0] + headland_m, positions_m[-1] - headland_m]``, cut
    into ``points`` equal segments; each point sits at its segment's centre, moved by up to
    ``± jitter / 2`` of a segment when ``jitter > 0`` (uniform, from ``seed``). Each point takes
    the nearest cell's depth.

    Parameters
    ----------
    positions_m : numpy.ndarray
        (cells,) the cells' positions along the travel, strictly increasing.
    depth_mm : numpy.ndarray
        (rows, cells) the true depth.
    points : int, optional
        Points per row, >= 1.
    headland_m : float, optional
        The stretch left out at each end.
    rows : sequence of int, optional
        The truth rows to sample (default: all).
    jitter : float, optional
        How far a point may move from its segment's centre, a fraction of the spacing in [0, 1].
    seed : int or numpy.random.Generator, optional
        The jitter's random source.

    Returns
    -------
    DepthSample
        The points' positions and depths, (rows, points).

    Raises
    ------
    ValueError
        Shapes that do not match, no points, a jitter out of range, headlands that leave nothing,
        or rows that do not exist.
    """
    pos = as_time(positions_m, "positions_m")
    depth = np.asarray(depth_mm, dtype=float)
    if depth.ndim != 2 or depth.shape[1] != pos.size:
        raise ValueError(f"depth_mm must be (rows, {pos.size}), got {depth.shape}")
    if points < 1:
        raise ValueError(f"points must be >= 1, got {points}")
    if not 0.0 <= jitter <= 1.0:
        raise ValueError(f"jitter is a fraction of the point spacing in [0, 1], got {jitter}")
    start, end = float(pos[0]) + headland_m, float(pos[-1]) - headland_m
    if not end > start:
        raise ValueError(f"headlands of {headland_m} m leave nothing of a "
                         f"{pos[-1] - pos[0]:.1f} m run")
    chosen = tuple(range(depth.shape[0])) if rows is None else tuple(int(r) for r in rows)
    if not chosen or min(chosen) < 0 or max(chosen) >= depth.shape[0]:
        raise ValueError(f"rows {chosen} not in 0..{depth.shape[0] - 1}")
    spacing = (end - start) / points
    where = np.tile(start + spacing * (np.arange(points) + 0.5), (len(chosen), 1))
    if jitter > 0:
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        where = where + spacing * jitter * rng.uniform(-0.5, 0.5, where.shape)
    right = np.clip(np.searchsorted(pos, where), 1, pos.size - 1)
    nearest = np.where(where - pos[right - 1] <= pos[right] - where, right - 1, right)
    values = depth[np.asarray(chosen)[:, None], nearest]
    return DepthSample(rows=chosen, positions_m=where, depth_mm=values)
