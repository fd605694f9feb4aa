"""Variable-rate application against a prescription map: rate per cell, zone transitions, sections.

Pure functions over the arrays of a recorded run: ``k`` samples of ``s`` sections, each value
held from its sample to the next (a section applies, at its rate, over the ground its centre
travels until the next sample). The positions, the prescribed rate under each section and the
ground that needed applying come from :mod:`hil.isobus.field` (``AsAppliedRecord.arrays``,
``PrescriptionMap.rate_at_local``, ``needed_ground``); nothing here knows about geometry.

**As-applied accuracy per cell** (:func:`cell_accuracy`). Over the samples where a section
applied, per map cell (a zone, or a square of a grid: :func:`grid_cells`), the area-weighted
mean applied rate against the area-weighted mean prescribed rate, in % of the prescribed. A
controller that ignores the map is off by the zones' spread; one that follows it only by its
own error. Samples just after a rate change can be left out (:func:`after_rate_change`): the
transition is judged on its own.

**Zone transitions** (:func:`transition_distances`). Where the prescribed rate under a
section steps by more than ``min_step_pct`` while the section applies, the distance along the
section's track from the boundary to where the applied rate enters and then *stays* within
``band_pct`` (5 %) of the new rate: the start of the in-band stretch that ends with the last
in-band sample before the next change (or the end of the run); leaving the band after that
last in-band sample is the next transition starting early (a TC's look-ahead), which the cell
accuracy judges. A rate that never enters the band before the next change reads ``inf``.

**Section switching** (:func:`section_switching`). Against where each section *should* have
applied (inside the work area, not already covered: ``needed_ground``), the metres applied on
ground that did not need it (**overlap**) and the metres not applied where it did (**skip**),
and each switch's position error: every on/off edge of the needed signal matched to the
nearest edge of the same direction in what the section did, within ``search_m`` (signed, +
late; a switch that never came reads ``inf``, one made far too early ``-inf``). Edges where the
work-area boundary is crossed are **headland** switches, the others **coverage** switches (over
an earlier pass). The overlap and skip totals integrate every sample; the per-kind sums add up
the switch events only (a section that is never needed on a pass, and applies on it all the
same, counts in the totals but has no event).

>>> import numpy as np
>>> d = np.arange(0.0, 20.0, 0.1)[:, None]                  # one section, 0.1 m samples
>>> needed = (d >= 5.0) & (d < 15.0)
>>> late = (d >= 6.0) & (d < 16.0)                           # switched 1 m late both times
>>> r = section_switching(d, late, needed)
>>> round(r.overlap_m, 3), round(r.skip_m, 3), [round(e.error_m, 3) for e in r.events]
(1.0, 1.0, [1.0, 1.0])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hil.metrics._common import DictMixin

__all__ = ["CellAccuracy", "CellResult", "SectionSwitching", "SwitchEvent", "Transition",
           "TransitionResult", "after_rate_change", "cell_accuracy", "grid_cells",
           "section_switching", "transition_distances"]


def _as_2d(name: str, value: ArrayLike, dtype: type = float) -> np.ndarray:
    arr = np.asarray(value, dtype=dtype)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{name} must be (samples,) or (samples, sections), got {arr.shape}")
    if dtype is float and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite values")
    return arr


def _same_shape(**arrays: np.ndarray) -> None:
    shapes = {name: a.shape for name, a in arrays.items()}
    if len(set(shapes.values())) != 1:
        raise ValueError(f"shapes differ: {shapes}")


def _interval_lengths(distance: np.ndarray) -> np.ndarray:
    """Distance travelled from each sample to the next (last sample: 0), (k, s)."""
    step = np.diff(distance, axis=0)
    if np.any(step < 0):
        raise ValueError("distance must not decrease along the samples")
    return np.vstack([step, np.zeros((1, distance.shape[1]))])


# ---------------------------------------------------------------- cells ---------------------

@dataclass(frozen=True)
class CellResult(DictMixin):
    """One cell of :func:`cell_accuracy`."""

    cell: int
    area_m2: float
    """Ground applied on in the cell (judged samples), m²."""
    prescribed: float
    """Area-weighted mean prescribed rate."""
    applied: float
    """Area-weighted mean applied rate."""
    error_pct: float
    """``100 (applied - prescribed) / prescribed``."""


@dataclass(frozen=True)
class CellAccuracy(DictMixin):
    """Result of :func:`cell_accuracy`."""

    cells: tuple[CellResult, ...]
    worst_abs_error_pct: float
    """Largest ``abs(error_pct)`` over the cells judged (NaN if none)."""
    mean_abs_error_pct: float
    """Area-weighted mean of ``abs(error_pct)``."""
    unprescribed_area_m2: float
    """Area applied on in cells whose prescribed rate is 0 (not expressible in %)."""


def grid_cells(east_m: ArrayLike, north_m: ArrayLike, cell_m: float,
               origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Integer id of the ``cell_m`` square grid cell under each point (same shape).

    Ids are unique per (column, row) for columns and rows within +-2**31.
    """
    if not cell_m > 0:
        raise ValueError("cell_m must be > 0")
    col = np.floor((np.asarray(east_m, dtype=float) - origin[0]) / cell_m).astype(np.int64)
    row = np.floor((np.asarray(north_m, dtype=float) - origin[1]) / cell_m).astype(np.int64)
    return (col << 32) + (row + (1 << 31))


def after_rate_change(distance_m: ArrayLike, prescribed: ArrayLike, settle_m: float) -> np.ndarray:
    """(k, s) True where the prescribed rate changed within the last ``settle_m`` of travel."""
    d = _as_2d("distance_m", distance_m)
    p = _as_2d("prescribed", prescribed)
    _same_shape(distance_m=d, prescribed=p)
    out = np.zeros(d.shape, dtype=bool)
    for j in range(d.shape[1]):
        change = np.flatnonzero(np.diff(p[:, j]) != 0) + 1
        for k in change:
            out[k:, j] |= d[k:, j] - d[k, j] < settle_m
    return out


def cell_accuracy(cell: ArrayLike, distance_m: ArrayLike, width_m: ArrayLike,
                  applying: ArrayLike, applied: ArrayLike, prescribed: ArrayLike, *,
                  exclude: ArrayLike | None = None, min_area_m2: float = 1.0) -> CellAccuracy:
    """As-applied accuracy per map cell (see the module docstring).

    Parameters
    ----------
    cell : (k, s) int
        Map cell under each section at each sample (zone index, or :func:`grid_cells`).
    distance_m : (k, s)
        Distance each section has travelled (non-decreasing).
    width_m : (s,)
        Section widths.
    applying : (k, s) bool
        The section applied from this sample to the next.
    applied, prescribed : (k, s)
        Applied and prescribed rate, one unit.
    exclude : (k, s) bool, optional
        Samples not judged (e.g. :func:`after_rate_change`).
    min_area_m2 : float
        Cells with less judged area are left out (a sliver at the edge of a pass).
    """
    d = _as_2d("distance_m", distance_m)
    c = _as_2d("cell", cell, np.int64)
    on = _as_2d("applying", applying, bool)
    a = _as_2d("applied", applied)
    p = _as_2d("prescribed", prescribed)
    _same_shape(cell=c, distance_m=d, applying=on, applied=a, prescribed=p)
    w = np.asarray(width_m, dtype=float).reshape(-1)
    if w.shape != (d.shape[1],) or np.any(w <= 0):
        raise ValueError(f"width_m must be {d.shape[1]} widths > 0")
    area = _interval_lengths(d) * w[None, :]
    judged = on & (area > 0)
    if exclude is not None:
        ex = _as_2d("exclude", exclude, bool)
        _same_shape(exclude=ex, applying=on)
        judged &= ~ex
    results: list[CellResult] = []
    unprescribed = 0.0
    for cid in np.unique(c[judged]):
        sel = judged & (c == cid)
        wa = area[sel]
        total = float(wa.sum())
        if total < min_area_m2:
            continue
        pres = float(np.sum(p[sel] * wa) / total)
        appl = float(np.sum(a[sel] * wa) / total)
        if pres <= 0:
            unprescribed += total
            continue
        results.append(CellResult(int(cid), total, pres, appl, 100.0 * (appl - pres) / pres))
    if results:
        errs = np.array([abs(r.error_pct) for r in results])
        areas = np.array([r.area_m2 for r in results])
        worst, mean = float(errs.max()), float(np.sum(errs * areas) / areas.sum())
    else:
        worst = mean = math.nan
    return CellAccuracy(tuple(results), worst, mean, unprescribed)


# ---------------------------------------------------------------- transitions ---------------

@dataclass(frozen=True)
class Transition(DictMixin):
    """One zone boundary crossed by one applying section."""

    section: int
    at_m: float
    """Distance along the section's track of the first sample with the new rate."""
    from_rate: float
    to_rate: float
    distance_m: float
    """From the boundary to where the applied rate stays within the band (inf: never)."""


@dataclass(frozen=True)
class TransitionResult(DictMixin):
    """Result of :func:`transition_distances`."""

    transitions: tuple[Transition, ...]
    worst_m: float
    """Largest distance (NaN when no boundary was crossed while applying)."""


def transition_distances(distance_m: ArrayLike, applying: ArrayLike, applied: ArrayLike,
                         prescribed: ArrayLike, *, band_pct: float = 5.0,
                         min_step_pct: float = 5.0,
                         hold_m: float | None = None) -> TransitionResult:
    """Distance from each zone boundary until the applied rate stays within ``band_pct``.

    The definition is in the module docstring. With ``hold_m``, the transition ends instead at
    the first sample from which the rate stays in the band for ``hold_m`` of travel (or to
    the end of the judged stretch, if shorter): what a noisy applied rate (a fluted roller's
    pulsation) calls reaching the new rate; what it does afterwards the cell accuracy judges.

    Arrays are (k, s) (or (k,) for one section) as in :func:`cell_accuracy`. A boundary counts
    when the prescribed rate steps by more than ``min_step_pct`` of the larger of the two rates
    and the section applies on both sides; the judged stretch ends at the next change or where
    the section stops applying.
    """
    d = _as_2d("distance_m", distance_m)
    on = _as_2d("applying", applying, bool)
    a = _as_2d("applied", applied)
    p = _as_2d("prescribed", prescribed)
    _same_shape(distance_m=d, applying=on, applied=a, prescribed=p)
    out: list[Transition] = []
    for j in range(d.shape[1]):
        change = np.flatnonzero(p[1:, j] != p[:-1, j]) + 1
        for n, k in enumerate(change):
            old, new = float(p[k - 1, j]), float(p[k, j])
            if abs(new - old) <= min_step_pct / 100.0 * max(abs(new), abs(old)):
                continue
            if not (on[k - 1, j] and on[k, j]):
                continue
            end = int(change[n + 1]) if n + 1 < change.size else d.shape[0]
            stops = np.flatnonzero(~on[k:end, j])
            if stops.size:
                end = k + int(stops[0])
            ok = np.abs(a[k:end, j] - new) <= band_pct / 100.0 * abs(new)
            if not ok.any():
                dist = math.inf
            elif hold_m is not None:
                dist = _held_entry(d[k:end, j], ok, hold_m)
            else:
                # judged up to the last sample in the band: leaving it just before the next
                # boundary is the next transition starting early (a look-ahead), not this one
                last = int(np.flatnonzero(ok)[-1])
                bad = np.flatnonzero(~ok[:last + 1])
                first = k + (int(bad[-1]) + 1 if bad.size else 0)
                dist = float(d[first, j] - d[k, j])
            out.append(Transition(j, float(d[k, j]), old, new, dist))
    worst = max((t.distance_m for t in out), default=math.nan)
    return TransitionResult(tuple(out), worst)


def _held_entry(d: np.ndarray, ok: np.ndarray, hold_m: float) -> float:
    """The distance from ``d[0]`` to the first in-band sample that stays in the band.

    Staying means for ``hold_m`` of travel, or to the end of the stretch; ``inf`` if none does.
    """
    run_start = None
    for i, good in enumerate(ok):
        if not good:
            run_start = None
            continue
        if run_start is None:
            run_start = i
        if d[i] - d[run_start] >= hold_m or i == ok.size - 1:
            return float(d[run_start] - d[0])
    return math.inf


# ---------------------------------------------------------------- sections ------------------

@dataclass(frozen=True)
class SwitchEvent(DictMixin):
    """One place where a section should have switched."""

    section: int
    kind: str
    """``headland`` (the work-area boundary) or ``coverage`` (ground covered before)."""
    direction: str
    """``on`` or ``off``."""
    at_m: float
    """Where it should have switched, along the section's track."""
    error_m: float
    """Where it did, minus ``at_m`` (+ late); +-inf if it did not within ``search_m`` (-inf: it
    was already in the new state, +inf: it stayed in the old one)."""
    overlap_m: float
    """Metres applied on ground that did not need it because of this switch."""
    skip_m: float
    """Metres not applied on ground that needed it because of this switch."""


@dataclass(frozen=True)
class SectionSwitching(DictMixin):
    """Result of :func:`section_switching`."""

    events: tuple[SwitchEvent, ...]
    overlap_m: float
    """Total metres (summed over sections) applied where not needed."""
    skip_m: float
    """Total metres not applied where needed."""
    worst_error_m: float
    """Largest ``abs(error_m)`` (NaN when there is no switch to judge)."""
    headland_overlap_m: float
    headland_skip_m: float
    coverage_overlap_m: float
    coverage_skip_m: float
    spurious_switches: int
    """Switches of a section that match no needed switch."""


def _edges(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices where a boolean series rises and falls."""
    dx = np.diff(x.astype(np.int8))
    return np.flatnonzero(dx > 0) + 1, np.flatnonzero(dx < 0) + 1


def section_switching(distance_m: ArrayLike, applying: ArrayLike, needed: ArrayLike, *,
                      inside_work_area: ArrayLike | None = None,
                      search_m: float = 10.0) -> SectionSwitching:
    """Overlap, skip and switch position errors of each section (see the module docstring).

    Parameters
    ----------
    distance_m : (k, s)
        Distance each section has travelled.
    applying : (k, s) bool
        What each section did (the ground truth of application), held to the next sample.
    needed : (k, s) bool
        Where it should have applied.
    inside_work_area : (k, s) bool, optional
        Whether each section was inside the work area; edges of ``needed`` where this also
        changes are headland switches. Without it every switch is a ``coverage`` one.
    search_m : float
        How far from a needed switch the section's own switch is looked for.
    """
    d = _as_2d("distance_m", distance_m)
    on = _as_2d("applying", applying, bool)
    need = _as_2d("needed", needed, bool)
    _same_shape(distance_m=d, applying=on, needed=need)
    inside = None
    if inside_work_area is not None:
        inside = _as_2d("inside_work_area", inside_work_area, bool)
        _same_shape(inside_work_area=inside, needed=need)
    step = _interval_lengths(d)
    overlap = float(np.sum(step[on & ~need]))
    skip = float(np.sum(step[~on & need]))
    events: list[SwitchEvent] = []
    spurious = 0
    for j in range(d.shape[1]):
        n_rise, n_fall = _edges(need[:, j])
        a_rise, a_fall = _edges(on[:, j])
        for direction, wanted, actual in (("on", n_rise, a_rise), ("off", n_fall, a_fall)):
            free = list(actual)
            for k in wanted:
                kind = "coverage"
                if inside is not None and inside[k, j] != inside[k - 1, j]:
                    kind = "headland"
                at = float(d[k, j])
                cand = [(abs(float(d[i, j]) - at), i) for i in free
                        if abs(float(d[i, j]) - at) <= search_m]
                if cand:
                    _, best = min(cand)
                    free.remove(best)
                    err = float(d[best, j]) - at
                    late, early = max(0.0, err), max(0.0, -err)
                    ov, sk = (early, late) if direction == "on" else (late, early)
                else:
                    # no such switch nearby: the section was already in the new state (switched
                    # far too early) or stayed in the old one (far too late, or never)
                    early = bool(on[k, j]) == (direction == "on")
                    err = -math.inf if early else math.inf
                    ov, sk = ((math.inf, 0.0) if bool(on[k, j]) else (0.0, math.inf))
                events.append(SwitchEvent(j, kind, direction, at, err, ov, sk))
            spurious += len(free)
    worst = max((abs(e.error_m) for e in events), default=math.nan)

    def total(kind: str, attr: str) -> float:
        return float(sum(getattr(e, attr) for e in events if e.kind == kind))
    return SectionSwitching(tuple(events), overlap, skip, worst,
                            total("headland", "overlap_m"), total("headland", "skip_m"),
                            total("coverage", "overlap_m"), total("coverage", "skip_m"),
                            spurious)
