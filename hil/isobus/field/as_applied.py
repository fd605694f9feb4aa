"""What was applied, where: the record of a run and its as-applied map (GeoJSON).

An :class:`AsAppliedRecord` keeps, per sample, the antenna's pose and per section whether it
applied and at what actual rate, each held until the next sample. It gives the arrays that
:mod:`hil.metrics.application_map` judges (:meth:`AsAppliedRecord.arrays`) and the as-applied
map: an RFC 7946 FeatureCollection, one polygon per section and per ``cell_length_m`` of travel
with its distance-weighted mean rate, which QGIS or any GIS tool opens beside the
prescription::

    {"type": "Feature",
     "properties": {"section": 0, "rate": 198.7, "unit": "kg/ha", "t_start_s": 4.2,
                    "t_end_s": 4.8},
     "geometry": {"type": "Polygon", "coordinates": [[[lon, lat], ...]]}}
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike
from shapely.geometry import mapping

from hil.isobus.field.boom import Boom
from hil.isobus.field.coverage import swath_quads
from hil.isobus.field.geodesy import LocalFrame

__all__ = ["AsAppliedArrays", "AsAppliedRecord"]


@dataclass(frozen=True)
class AsAppliedArrays:
    """A record as arrays: ``k`` samples, ``s`` sections."""

    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    leg: np.ndarray
    """Path leg per sample (-1 where the pose had none)."""
    applying: np.ndarray
    """(k, s) bool: the section applied from this sample to the next."""
    rate: np.ndarray
    """(k, s) actual rate, in the record's unit (0 where not applying)."""
    centre_east_m: np.ndarray
    """(k, s) each section's centre on the ground."""
    centre_north_m: np.ndarray
    section_distance_m: np.ndarray
    """(k, s) distance each section's centre has travelled since the first sample."""


class AsAppliedRecord:
    """Samples of what a boom applied (see the module docstring)."""

    def __init__(self, boom: Boom, frame: LocalFrame, unit: str) -> None:
        self.boom = boom
        self.frame = frame
        self.unit = unit
        self._rows: list[tuple[float, float, float, float, int]] = []
        self._applying: list[tuple[bool, ...]] = []
        self._rate: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, pose: Any, applying: Sequence[bool], rate: ArrayLike) -> None:
        """Add a sample: ``pose`` (``t_s``, ``east_m``, ``north_m``, ``heading_deg``, optional
        ``leg``), per section whether it applies and its actual rate from now on."""
        rates = np.asarray(rate, dtype=float)
        n = len(self.boom.sections)
        if len(applying) != n or rates.shape != (n,):
            raise ValueError(f"{len(applying)} states and {rates.shape} rates for {n} sections")
        if self._rows and pose.t_s <= self._rows[-1][0]:
            raise ValueError(f"sample at {pose.t_s} s is not after the last one")
        self._rows.append((float(pose.t_s), float(pose.east_m), float(pose.north_m),
                           float(pose.heading_deg), int(getattr(pose, "leg", -1))))
        self._applying.append(tuple(bool(a) for a in applying))
        self._rate.append(np.where(np.asarray(applying, dtype=bool), rates, 0.0))

    def arrays(self) -> AsAppliedArrays:
        """The record as arrays."""
        if not self._rows:
            raise ValueError("the record is empty")
        rows = np.array(self._rows)
        _, centre, _ = self.boom.section_lines(rows[:, 1], rows[:, 2], rows[:, 3])
        step = np.hypot(*np.diff(centre, axis=0).transpose(2, 0, 1))
        dist = np.vstack([np.zeros((1, centre.shape[1])), np.cumsum(step, axis=0)])
        return AsAppliedArrays(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                               rows[:, 4].astype(np.int64), np.array(self._applying),
                               np.array(self._rate), centre[..., 0], centre[..., 1], dist)

    def to_geojson(self, *, cell_length_m: float = 1.0) -> dict[str, Any]:
        """The as-applied map: polygons of at most ``cell_length_m`` of travel per section."""
        if not cell_length_m > 0:
            raise ValueError("cell_length_m must be > 0")
        a = self.arrays()
        left, _, right = self.boom.section_lines(a.east_m, a.north_m, a.heading_deg)
        features: list[dict[str, Any]] = []
        for j in range(len(self.boom.sections)):
            quads = swath_quads(left[:, j], right[:, j])
            step = np.diff(a.section_distance_m[:, j])
            on = a.applying[:-1, j]
            k = 0
            while k < on.size:
                if not on[k]:
                    k += 1
                    continue
                end, travelled = k, 0.0
                while end < on.size and on[end] and (travelled < cell_length_m or end == k):
                    travelled += step[end]
                    end += 1
                if travelled > 0:
                    w = step[k:end]
                    rate = float(np.sum(a.rate[k:end, j] * w) / np.sum(w))
                    poly = shapely.union_all(quads[k:end])
                    features.append({
                        "type": "Feature",
                        "properties": {"section": j, "rate": round(rate, 3), "unit": self.unit,
                                       "t_start_s": round(float(a.t_s[k]), 3),
                                       "t_end_s": round(float(a.t_s[end]), 3)},
                        "geometry": mapping(self._lonlat(poly))})
                k = end
        return json.loads(json.dumps({"type": "FeatureCollection", "features": features}))

    def _lonlat(self, geom: Any) -> Any:
        def unproject(c: np.ndarray) -> np.ndarray:
            lon, lat = self.frame.to_wgs84(c[:, 0], c[:, 1])
            return np.column_stack([np.round(lon, 9), np.round(lat, 9)])
        return shapely.transform(geom, unproject)

    def save_geojson(self, path: str | Path, *, cell_length_m: float = 1.0) -> None:
        """Write the as-applied map to ``path``."""
        Path(path).write_text(json.dumps(self.to_geojson(cell_length_m=cell_length_m)) + "\n",
                              encoding="utf-8")
