"""What a depth field run under the Task Controller really sowed, and where: the truth the depth
rig's ``isobus`` suite judges (``test_depth_isobus.py``).

Every truth cell of the run (one per 10 mm of travel, a true depth per row) is placed where the
seed line was when the planter had travelled that far (the rig traces the seed line's middle,
``seed_east_m`` / ``seed_north_m``, its heading and whether the tractor is on a pass) and stamped
with that run time; the map's depth there is its zone's. From those:

- :func:`judged_cells`: the cells on the passes away from the zone boundaries (the map's depth
  the same ``margin_m`` ahead and behind along the heading);
- :func:`held_entry`: where a smoothed depth enters a band and stays for a stretch of travel
  (a transition's end, a fall-back's); :func:`early_departure`: how far before a boundary it
  left the old zone's band (a transition's start);
- :func:`reported_at`: the implement's last reported actual depth (DDI 57) at given times;
- :func:`standstill_rod_travel`: how far the rod moved while the machine stood, once it had
  driven.

Nothing here reads the DUT's own view of its depth but :func:`reported_at`, which is what is
judged against the truth.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.isobus.field import load_field, load_prescription
from hil.isobus.field.prescription import PrescriptionMap

__all__ = ["SMOOTH_M", "SeedLineTruth", "early_departure", "held_entry", "judged_cells",
           "reported_at",
           "seed_line_truth", "smoothed", "standstill_rod_travel"]

#: the truth cells' spacing along the path (the rig's: one per 10 mm of travel)
CELL_M = 0.01
#: a depth is read as the mean over the rows and over this much travel, centred: a seed line's
#: depth, not one seed's (the soil's clods swing single seeds by millimetres)
SMOOTH_M = 0.5
#: below this ground speed (m/s) the machine stands (the rig's own standstill test's)
STANDING_MPS = 0.01


@dataclass(frozen=True)
class SeedLineTruth:
    """The run's truth cells, ``c`` of them along the path, ``r`` rows."""

    distance_m: np.ndarray
    """(c,) the planter's travel at the cell."""
    depth_mm: np.ndarray
    """(c, r) true seed depth per row."""
    t_s: np.ndarray
    """(c,) the run time the seed line was there."""
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    on_pass: np.ndarray
    """(c,) bool: the tractor was on a pass (not a headland turn, not the overlap pass)."""
    zone_mm: np.ndarray
    """(c,) the map's depth at the cell (nan without a map)."""

    @property
    def line_mm(self) -> np.ndarray:
        """(c,) the seed line's depth: the mean over the rows, smoothed over
        :data:`SMOOTH_M` of travel."""
        return smoothed(self.depth_mm.mean(axis=1), round(SMOOTH_M / CELL_M))


def smoothed(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving mean of ``window`` samples (shorter at the ends, never padded)."""
    x = np.asarray(x, dtype=float)
    if window <= 1 or x.size == 0:
        return x.copy()
    c = np.concatenate([[0.0], np.cumsum(x)])
    half = window // 2
    i = np.arange(x.size)
    lo, hi = np.clip(i - half, 0, x.size), np.clip(i - half + window, 0, x.size)
    return (c[hi] - c[lo]) / (hi - lo)


def seed_line_truth(traces: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray],
                    rx: PrescriptionMap | None) -> SeedLineTruth:
    """The truth cells of a run placed on the field.

    Raises
    ------
    ValueError
        The traces lack the field run's signals, or the run has no truth cells.
    """
    for name in ("time_s", "distance_m", "seed_east_m", "seed_north_m", "heading_deg",
                 "on_pass"):
        if name not in traces:
            raise ValueError(f"traces.npz has no {name!r}: not a depth field run under a TC")
    cells_d = np.asarray(truth.get("distance_m", np.empty(0)), dtype=float)
    if cells_d.size == 0:
        raise ValueError("the run has no truth cells (the planter never moved)")
    distance = np.asarray(traces["distance_m"], dtype=float)
    moving = np.concatenate([[True], np.diff(distance) > 0.0])
    d, idx = distance[moving], np.flatnonzero(moving)
    at = idx[np.clip(np.searchsorted(d, cells_d), 0, d.size - 1)]
    east = np.asarray(traces["seed_east_m"])[at]
    north = np.asarray(traces["seed_north_m"])[at]
    zone = (np.asarray(rx.rate_at_local(east, north), dtype=float) if rx is not None
            else np.full(cells_d.shape, math.nan))
    return SeedLineTruth(cells_d, np.asarray(truth["depth_mm"], dtype=float),
                         np.asarray(traces["time_s"], dtype=float)[at], east, north,
                         np.asarray(traces["heading_deg"], dtype=float)[at],
                         np.asarray(traces["on_pass"])[at] > 0.5, zone)


def load_run_truth(record: Mapping[str, Any], traces: Mapping[str, np.ndarray],
                   truth: Mapping[str, np.ndarray]) -> tuple[SeedLineTruth, PrescriptionMap | None]:
    """:func:`seed_line_truth` of a recorded run, its map read from the files its truth names."""
    run = record["truth"]["field_run"]
    field = load_field(run["field"])
    rx = (load_prescription(run["prescription"], frame=field.frame)
          if run.get("prescription") else None)
    return seed_line_truth(traces, truth, rx), rx


def judged_cells(cells: SeedLineTruth, rx: PrescriptionMap, margin_m: float) -> np.ndarray:
    """(c,) bool: on a pass, and the map's depth the same ``margin_m`` ahead and behind."""
    heading = np.radians(cells.heading_deg)
    fwd_e, fwd_n = np.sin(heading) * margin_m, np.cos(heading) * margin_m
    ahead = np.asarray(rx.rate_at_local(cells.east_m + fwd_e, cells.north_m + fwd_n), dtype=float)
    behind = np.asarray(rx.rate_at_local(cells.east_m - fwd_e, cells.north_m - fwd_n),
                        dtype=float)
    return cells.on_pass & (cells.zone_mm == ahead) & (cells.zone_mm == behind)


def held_entry(distance_m: np.ndarray, ok: np.ndarray, hold_m: float) -> int | None:
    """Index of the first cell from which ``ok`` holds for ``hold_m`` of travel (or to the end
    of the arrays, if shorter); None if none does."""
    d = np.asarray(distance_m, dtype=float)
    good = np.asarray(ok, dtype=bool)
    start = None
    for i in range(good.size):
        if not good[i]:
            start = None
            continue
        if start is None:
            start = i
        if d[i] - d[start] >= hold_m:
            return start
    return start


def early_departure(distance_m: np.ndarray, ok_old: np.ndarray, start: int, k: int) -> float:
    """How far before cell ``k`` (a boundary) the depth last left the old zone's band: the
    travel from the first cell of the run of cells out of it that ends at ``k``, within
    ``start .. k`` (the stretch since the previous boundary); 0 when ``k - 1`` is in it."""
    d = np.asarray(distance_m, dtype=float)
    inside = np.flatnonzero(np.asarray(ok_old[start:k], dtype=bool))
    first_out = start + (int(inside[-1]) + 1 if inside.size else 0)
    return float(d[k] - d[first_out]) if first_out < k else 0.0


def reported_at(t_s: np.ndarray, reported: Mapping[str, Sequence[float]]) -> np.ndarray:
    """The implement's last reported actual depth (DDI 57, mm) at each of ``t_s``: the value
    holds until the next report; nan before the first."""
    times = np.asarray(reported.get("t_s", []), dtype=float)
    values = np.asarray(reported.get("depth_mm", []), dtype=float)
    t = np.asarray(t_s, dtype=float)
    if times.size == 0:
        return np.full(t.shape, math.nan)
    k = np.searchsorted(times, t, side="right") - 1
    return np.where(k >= 0, values[np.clip(k, 0, None)], math.nan)


def standstill_rod_travel(traces: Mapping[str, np.ndarray]) -> tuple[float, float]:
    """(rod travel in mm, seconds standing) while the machine stood after it had first moved:
    the seed depth cannot change then, so a controller has nothing to chase."""
    t = np.asarray(traces["time_s"], dtype=float)
    speed = np.asarray(traces["ground_speed_mps"], dtype=float)
    rod = np.asarray(traces["rod_position_mm"], dtype=float)
    moved = np.flatnonzero(speed >= STANDING_MPS)
    if moved.size == 0:
        return 0.0, 0.0
    standing = speed < STANDING_MPS
    standing[:moved[0]] = False
    both = standing[1:] & standing[:-1]
    travel = float(np.sum(np.abs(np.diff(rod))[both]))
    return travel, float(np.sum(np.diff(t)[both]))
