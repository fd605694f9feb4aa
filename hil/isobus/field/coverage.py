"""TC-SC section control: coverage as the union of applied swaths, and when each section is on.

**Coverage.** Every recorded interval in which a section applied adds the quadrilateral its
line swept (the convex hull of the line at both ends: in a turn the exact sweep is a bow tie,
the hull over-covers it by at most the line's rotation times half its width). Quadrilaterals
of finished runs are merged and kept in an STRtree.

**The rule.** A section is *wanted* at a pose when its **probe** there, the rectangle of the
section's width from its line to ``probe_m`` ahead, lies on fresh ground (inside the work area
and not yet covered) for some part, with no more than ``overlap_tolerance_pct`` of it on ground
that is covered or outside the work area. 0 % switches off at the first overlap (skips rather
than overlaps), 100 % keeps a section on while any of it is on fresh ground (overlaps rather
than skips), and 50 % (the default) switches where the section's centre crosses, within
``probe_m / 2``. An off section is switched on when it will be wanted ``turn_on_s`` from now,
an on section off when it will not be wanted ``turn_off_s`` from now (the implement's declared
look-ahead times, :class:`~.boom.Boom`): the command then takes effect where it should. A
switch is never judged at a time before the previous command of that section takes effect
(with a turn-on time longer than the turn-off time, an "off" checked right after an "on" would
look at ground the section has not reached, and flap).

The probe is ahead of the line, so a section's own swath (which ends at its line) never counts
as covered for it. The future pose comes from a callable: the field path where the rig drives
a known path, or :func:`dead_reckoning` from the last GNSS fix, as a tractor's TC does.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from hil.isobus.field.boom import Boom

__all__ = ["Coverage", "PoseLike", "SectionControl", "dead_reckoning", "needed_ground",
           "swath_quads"]


_RUN_CHUNK = 64
"""Swaths of an open run merged into one polygon every this many intervals."""


class PoseLike(Protocol):
    """What section control needs of a pose (e.g. :class:`~.path.Pose`)."""

    @property
    def east_m(self) -> float: ...
    @property
    def north_m(self) -> float: ...
    @property
    def heading_deg(self) -> float: ...


@dataclass(frozen=True)
class _Fix:
    east_m: float
    north_m: float
    heading_deg: float


def dead_reckoning(pose: PoseLike, speed_m_s: float, t_s: float) -> Callable[[float], _Fix]:
    """Poses predicted from one fix at time ``t_s``: straight on at ``speed_m_s``."""
    h = math.radians(pose.heading_deg)

    def at(t: float) -> _Fix:
        d = speed_m_s * (t - t_s)
        return _Fix(pose.east_m + d * math.sin(h), pose.north_m + d * math.cos(h),
                    pose.heading_deg)
    return at


def swath_quads(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Shapely polygons swept by a line between consecutive samples.

    ``left`` and ``right`` are the line's ends, shape ``(k, 2)``; returns ``k - 1`` polygons
    (convex hulls of the line at both ends of each interval).
    """
    if len(left) < 2:
        return np.empty(0, dtype=object)
    rings = np.stack([left[:-1], right[:-1], right[1:], left[1:], left[:-1]], axis=1)
    return shapely.convex_hull(shapely.polygons(rings))


class Coverage:
    """The ground a boom has applied on: per-section runs, merged when a run ends."""

    def __init__(self, boom: Boom) -> None:
        self.boom = boom
        self._closed: list[BaseGeometry] = []
        self._tree: shapely.STRtree | None = None
        self._open: list[list[BaseGeometry]] = [[] for _ in boom.sections]
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._last_on: tuple[bool, ...] = (False,) * len(boom.sections)

    def record(self, pose: PoseLike, applying: Sequence[bool]) -> None:
        """Add a fix and which sections apply from now on (the implement's actual states).

        The interval since the previous fix is covered by the sections that applied during it
        (the states given with the previous fix).
        """
        if len(applying) != len(self.boom.sections):
            raise ValueError(f"{len(applying)} states for {len(self.boom.sections)} sections")
        left, _, right = self.boom.section_lines(pose.east_m, pose.north_m, pose.heading_deg)
        if self._last is not None:
            for j, on in enumerate(self._last_on):
                if on:
                    quad = swath_quads(np.stack([self._last[0][0, j], left[0, j]]),
                                       np.stack([self._last[1][0, j], right[0, j]]))[0]
                    if quad.area > 0:
                        self._open[j].append(quad)
        for j, on in enumerate(applying):
            # a finished run, or a long one (its older part is merged: queries stay short)
            if self._open[j] and (not on or len(self._open[j]) >= _RUN_CHUNK):
                self._close(j)
        self._last = (left, right)
        self._last_on = tuple(bool(a) for a in applying)

    def _close(self, j: int) -> None:
        self._closed.append(shapely.union_all(self._open[j]))
        self._open[j] = []
        self._tree = None

    def covered_area(self, probe: BaseGeometry) -> float:
        """Area (m²) of ``probe`` that is covered."""
        parts: list[BaseGeometry] = []
        if self._closed:
            if self._tree is None:
                self._tree = shapely.STRtree(self._closed)
            parts.extend(self._closed[i] for i in self._tree.query(probe, predicate="intersects"))
        for run in self._open:
            if run:
                arr = np.array(run, dtype=object)
                parts.extend(arr[shapely.intersects(arr, probe)])
        if not parts:
            return 0.0
        # clip first: the union of a few probe-sized pieces, not of whole passes
        pieces = shapely.intersection(np.array(parts, dtype=object), probe)
        pieces = pieces[~shapely.is_empty(pieces)]
        if pieces.size == 0:
            return 0.0
        if pieces.size == 1:
            return float(pieces[0].area)
        return float(shapely.union_all(pieces).area)

    def geometry(self) -> BaseGeometry:
        """All covered ground as one (multi)polygon."""
        return shapely.union_all(self._closed + [q for run in self._open for q in run])


class SectionControl:
    """Desired on/off state of each section from coverage, work area and look-ahead.

    Parameters
    ----------
    boom : Boom
        Sections and the look-ahead times.
    work_area : Polygon
        Where to apply (the field less its headlands), local plane.
    overlap_tolerance_pct : float
        0-100, see the module docstring.
    probe_m : float
        Length of the probe ahead of a section's line (> 0).
    """

    def __init__(self, boom: Boom, work_area: Polygon, *, overlap_tolerance_pct: float = 50.0,
                 probe_m: float = 0.1) -> None:
        if not 0.0 <= overlap_tolerance_pct <= 100.0:
            raise ValueError(f"overlap tolerance {overlap_tolerance_pct} % is outside 0..100")
        if not probe_m > 0:
            raise ValueError("probe_m must be > 0")
        self.boom = boom
        self.work_area = work_area
        shapely.prepare(work_area)
        self.tolerance = overlap_tolerance_pct / 100.0
        self.probe_m = probe_m
        self.coverage = Coverage(boom)
        self.states: tuple[bool, ...] = (False,) * len(boom.sections)
        self._effect = [-math.inf] * len(boom.sections)

    def probes(self, pose: PoseLike) -> list[Polygon]:
        """Each section's probe at ``pose``."""
        left, _, right = self.boom.section_lines(pose.east_m, pose.north_m, pose.heading_deg)
        h = math.radians(pose.heading_deg)
        ahead = self.probe_m * np.array([math.sin(h), math.cos(h)])
        return [Polygon([left[0, j], right[0, j], right[0, j] + ahead, left[0, j] + ahead])
                for j in range(len(self.boom.sections))]

    def overlap_fractions(self, pose: PoseLike) -> np.ndarray:
        """Per section, the fraction of its probe that is covered or outside the work area."""
        out = []
        for probe in self.probes(pose):
            inside = probe.intersection(self.work_area)
            fresh = inside.area - self.coverage.covered_area(inside) if inside.area > 0 else 0.0
            out.append(1.0 - max(fresh, 0.0) / probe.area)
        return np.array(out)

    def wanted(self, pose: PoseLike) -> np.ndarray:
        """Per section: is the ground under its probe at ``pose`` to be applied on?"""
        frac = self.overlap_fractions(pose)
        return (frac < 1.0 - 1e-9) & (frac <= self.tolerance + 1e-9)

    def update(self, t_s: float, pose_at: Callable[[float], PoseLike]) -> tuple[bool, ...]:
        """The commanded states at ``t_s`` (kept as :attr:`states`).

        ``pose_at(t)`` gives the antenna's pose at a future time ``t``.
        """
        wanted: dict[float, np.ndarray] = {}

        def wanted_at(t: float) -> np.ndarray:
            if t not in wanted:
                wanted[t] = self.wanted(pose_at(t))
            return wanted[t]

        states = list(self.states)
        for j, was in enumerate(self.states):
            # a switch is judged where it would take effect, but never before the previous
            # command has: an off right after an on (turn-on time > turn-off time) would
            # otherwise look at ground the section has not reached yet, and flap
            lag = self.boom.turn_off_s if was else self.boom.turn_on_s
            check = max(t_s + lag, self._effect[j])
            if bool(wanted_at(check)[j]) != was:
                states[j] = not was
                self._effect[j] = t_s + lag
        self.states = tuple(states)
        return self.states

    def record(self, pose: PoseLike, applying: Sequence[bool]) -> None:
        """Add a fix and the implement's actual section states to the coverage."""
        self.coverage.record(pose, applying)


def needed_ground(boom: Boom, east_m: np.ndarray, north_m: np.ndarray, heading_deg: np.ndarray,
                  leg: np.ndarray, applied: np.ndarray, work_area: Polygon) -> np.ndarray:
    """Where each section *should* have applied, for judging a recorded run.

    A section's centre at sample ``k`` is on ground that needs applying when it is inside the
    work area and not covered by what any section applied on an earlier leg of the path
    (``applied[k, j]``: section ``j`` applied from sample ``k`` to ``k + 1``). Returns a
    ``(k, s)`` boolean array: the reference for :mod:`hil.metrics.application_map`.
    """
    left, centre, right = boom.section_lines(east_m, north_m, heading_deg)
    applied = np.asarray(applied, dtype=bool)
    leg = np.asarray(leg)
    k, s = centre.shape[:2]
    if applied.shape != (k, s) or leg.shape != (k,):
        raise ValueError(f"applied must be {(k, s)} and leg {(k,)}, got {applied.shape}, "
                         f"{leg.shape}")
    quads = np.empty((k - 1, s), dtype=object) if k > 1 else np.empty((0, s), dtype=object)
    for j in range(s):
        quads[:, j] = swath_quads(left[:, j], right[:, j])
    needed = shapely.contains_xy(work_area, centre[..., 0], centre[..., 1])
    for this_leg in np.unique(leg):
        rows = np.flatnonzero(leg == this_leg)
        # interval k -> k+1 counts as covered before this leg if it ended in an earlier one
        # (so the swath that ends on a section's line at a leg's first sample is not "before")
        earlier = (leg[1:] < this_leg)[:, None] & applied[:-1]
        if earlier.any():
            covered = shapely.union_all(quads[earlier])
            shapely.prepare(covered)
            hit = shapely.contains_xy(covered, centre[rows, :, 0], centre[rows, :, 1])
            needed[rows] &= ~hit
    return needed
