"""A field path: the legs a tractor drives (passes, headland turns), with their speeds.

A path is a chain of **legs**. Each leg is a polyline in the local plane with a ``kind``
(``pass``, ``overlap``, ``turn`` or ``transit``) and a speed that changes linearly in time
from ``speed_m_s[0]`` at its start to ``speed_m_s[1]`` at its end (constant acceleration along
the leg). Sampled at run time ``t`` the path gives the antenna's position, heading and ground
speed (:class:`Pose`); after its end the tractor stands still at the last point. Because the
speed is piecewise linear in time, :meth:`FieldPath.speed_profile` is exactly a scenario's
``speed_profile`` ((t, v) breakpoints).

The file format (a "field file", :func:`load_field`) is an RFC 7946 GeoJSON FeatureCollection
in WGS84 lon/lat::

    {"type": "FeatureCollection",
     "features": [
       {"type": "Feature", "properties": {"role": "boundary"},
        "geometry": {"type": "Polygon", ...}},
       {"type": "Feature", "properties": {"role": "work_area"},
        "geometry": {"type": "Polygon", ...}},
       {"type": "Feature", "properties": {"role": "leg", "kind": "pass", "speed_m_s": [0, 1.67]},
        "geometry": {"type": "LineString", ...}},
       ...]}

``boundary`` is the field; ``work_area`` (optional, default the boundary) is where the
implement should apply (the field less its headlands); the ``leg`` features, in driving order,
must join end to start (within 0.05 m). :func:`rectangular_field` generates such a field.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike
from shapely.geometry import LineString, Polygon, box, mapping, shape

from hil.errors import ConfigError
from hil.isobus.field.geodesy import LocalFrame

__all__ = ["LEG_KINDS", "Field", "FieldPath", "Leg", "PathSamples", "Pose", "field_from_geojson",
           "field_to_geojson", "load_field", "rectangular_field"]

LEG_KINDS = ("pass", "overlap", "turn", "transit")
"""What a leg is: a working pass, the pass that overlaps ground already covered, a headland
turn, or driving between (kinds label the path for the metrics; sections follow coverage)."""
JOIN_TOLERANCE_M = 0.05
"""Largest gap allowed between one leg's end and the next leg's start."""


@dataclass(frozen=True)
class Leg:
    """One leg: a polyline (local m, shape (k, 2), k >= 2) driven from ``v0`` to ``v1`` m/s."""

    kind: str
    points: np.ndarray
    v0_m_s: float
    v1_m_s: float

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[0] < 2 or pts.shape[1] != 2:
            raise ValueError(f"a leg needs at least two (east, north) points, got {pts.shape}")
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.any(np.diff(pts, axis=0) != 0.0, axis=1)  # repeated vertices add nothing
        pts = pts[keep]
        if pts.shape[0] < 2:
            raise ValueError("a leg has zero length")
        if self.kind not in LEG_KINDS:
            raise ValueError(f"leg kind {self.kind!r} is not one of {', '.join(LEG_KINDS)}")
        if min(self.v0_m_s, self.v1_m_s) < 0 or self.v0_m_s + self.v1_m_s <= 0:
            raise ValueError(f"leg speeds {self.v0_m_s}, {self.v1_m_s} m/s: both >= 0 and not "
                             "both 0 (a stop is the end of the path)")
        object.__setattr__(self, "points", pts)

    @property
    def length_m(self) -> float:
        """Length along the polyline, m."""
        return float(np.sum(np.hypot(*np.diff(self.points, axis=0).T)))

    @property
    def duration_s(self) -> float:
        """Time to drive it: length / mean speed (constant acceleration)."""
        return 2.0 * self.length_m / (self.v0_m_s + self.v1_m_s)


@dataclass(frozen=True)
class Pose:
    """Where the GNSS antenna is at time ``t_s``."""

    t_s: float
    east_m: float
    north_m: float
    heading_deg: float
    """Course over ground, degrees clockwise from north (0..360)."""
    speed_m_s: float
    distance_m: float
    """Distance driven since the path's start."""
    leg: int
    """Index of the leg being driven (the last leg after the end)."""
    kind: str


@dataclass(frozen=True)
class PathSamples:
    """:class:`Pose` fields as arrays, one entry per requested time."""

    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    speed_m_s: np.ndarray
    distance_m: np.ndarray
    leg: np.ndarray


class FieldPath:
    """Legs chained in driving order, sampled in run time (see the module docstring)."""

    def __init__(self, legs: Sequence[Leg]) -> None:
        if not legs:
            raise ValueError("a path needs at least one leg")
        for i in range(1, len(legs)):
            gap = float(np.hypot(*(legs[i].points[0] - legs[i - 1].points[-1])))
            if gap > JOIN_TOLERANCE_M:
                raise ValueError(f"leg {i} starts {gap:.3f} m from the end of leg {i - 1}")
        # snap each leg's start onto the previous leg's end: one continuous chain of vertices
        snapped = [legs[0]]
        for leg in legs[1:]:
            pts = np.vstack([snapped[-1].points[-1:], leg.points[1:]])
            snapped.append(Leg(leg.kind, pts, leg.v0_m_s, leg.v1_m_s))
        self.legs = tuple(snapped)
        durations = np.array([leg.duration_s for leg in self.legs])
        lengths = np.array([leg.length_m for leg in self.legs])
        self._t0 = np.concatenate([[0.0], np.cumsum(durations)])
        self._s0 = np.concatenate([[0.0], np.cumsum(lengths)])
        self._v0 = np.array([leg.v0_m_s for leg in self.legs])
        self._acc = (np.array([leg.v1_m_s for leg in self.legs]) - self._v0) / durations
        self._pts = np.vstack([self.legs[0].points] + [leg.points[1:] for leg in self.legs[1:]])
        d = np.diff(self._pts, axis=0)
        self._seg_len = np.hypot(d[:, 0], d[:, 1])
        self._dist = np.concatenate([[0.0], np.cumsum(self._seg_len)])
        self._seg_heading = np.degrees(np.arctan2(d[:, 0], d[:, 1])) % 360.0

    @property
    def duration_s(self) -> float:
        """Time to drive the whole path, s."""
        return float(self._t0[-1])

    @property
    def length_m(self) -> float:
        """Length of the whole path, m."""
        return float(self._s0[-1])

    def sample(self, t_s: ArrayLike) -> PathSamples:
        """The pose at each time (s, >= 0); after the end, standing at the last point."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if not np.all(np.isfinite(t)) or np.any(t < 0):
            raise ValueError("path times must be finite and >= 0")
        leg = np.clip(np.searchsorted(self._t0, t, side="right") - 1, 0, len(self.legs) - 1)
        tau = np.minimum(t - self._t0[leg], self._t0[leg + 1] - self._t0[leg])
        s_in = self._v0[leg] * tau + 0.5 * self._acc[leg] * tau * tau
        s = np.minimum(self._s0[leg] + s_in, self._s0[-1])
        speed = np.where(t >= self._t0[-1], 0.0, self._v0[leg] + self._acc[leg] * tau)
        seg = np.clip(np.searchsorted(self._dist, s, side="right") - 1, 0, self._seg_len.size - 1)
        frac = np.clip((s - self._dist[seg]) / self._seg_len[seg], 0.0, 1.0)
        pos = self._pts[seg] + frac[:, None] * (self._pts[seg + 1] - self._pts[seg])
        return PathSamples(t, pos[:, 0], pos[:, 1], self._seg_heading[seg], speed, s, leg)

    def pose(self, t_s: float) -> Pose:
        """The antenna's :class:`Pose` at run time ``t_s``."""
        p = self.sample(t_s)
        leg = int(p.leg[0])
        return Pose(float(p.t_s[0]), float(p.east_m[0]), float(p.north_m[0]),
                    float(p.heading_deg[0]), float(p.speed_m_s[0]), float(p.distance_m[0]),
                    leg, self.legs[leg].kind)

    def speed_profile(self) -> tuple[tuple[float, float], ...]:
        """(time s, speed m/s) breakpoints, exact (the speed is linear within each leg)."""
        points: list[tuple[float, float]] = []
        for t0, leg in zip(self._t0[:-1], self.legs, strict=True):
            points.append((float(t0), leg.v0_m_s))
            points.append((float(t0 + leg.duration_s), leg.v1_m_s))
        # a speed jump between legs: keep both values 1 ms apart (scenario times must increase)
        out: list[tuple[float, float]] = [points[0]]
        for t, v in points[1:]:
            if t <= out[-1][0] + 1e-6:
                if abs(v - out[-1][1]) < 1e-12:
                    continue
                t = out[-1][0] + 0.001
            out.append((round(t, 6), v))
        return tuple(out)

    def leg_time_span(self, index: int) -> tuple[float, float]:
        """Start and end time of leg ``index``, s."""
        return float(self._t0[index]), float(self._t0[index + 1])


@dataclass(frozen=True)
class Field:
    """A field: its boundary, where to apply, and the path driven over it (local plane)."""

    frame: LocalFrame
    boundary: Polygon
    work_area: Polygon
    path: FieldPath
    source: str = field(default="<memory>", compare=False)


def _leg_from_feature(feature: Mapping[str, Any], frame: LocalFrame, source: str,
                      key: str) -> Leg:
    props = feature["properties"]
    kind = props.get("kind")
    if kind not in LEG_KINDS:
        raise ConfigError(f"kind {kind!r} is not one of {', '.join(LEG_KINDS)}", path=source,
                          key=f"{key}.properties.kind")
    speed = props.get("speed_m_s")
    if isinstance(speed, (int, float)) and not isinstance(speed, bool):
        speed = [speed, speed]
    if (not isinstance(speed, list) or len(speed) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in speed)):
        raise ConfigError("must be a speed in m/s or [start, end] speeds", path=source,
                          key=f"{key}.properties.speed_m_s")
    geom = feature.get("geometry")
    if not isinstance(geom, Mapping) or geom.get("type") != "LineString":
        raise ConfigError("a leg's geometry must be a LineString", path=source,
                          key=f"{key}.geometry")
    try:
        coords = np.asarray(geom["coordinates"], dtype=float)
        e, n = frame.to_local(coords[:, 0], coords[:, 1])
        return Leg(kind, np.column_stack([e, n]), float(speed[0]), float(speed[1]))
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise ConfigError(f"bad leg: {exc}", path=source, key=key) from None


def _polygon_from_feature(feature: Mapping[str, Any], frame: LocalFrame, source: str,
                          key: str) -> Polygon:
    geom = feature.get("geometry")
    if not isinstance(geom, Mapping) or geom.get("type") != "Polygon":
        raise ConfigError("must be a Polygon", path=source, key=f"{key}.geometry")
    try:
        poly = shape(geom)
    except (ValueError, TypeError, AttributeError, IndexError) as exc:
        raise ConfigError(f"malformed coordinates: {exc}", path=source,
                          key=f"{key}.geometry") from None

    def project(c: np.ndarray) -> np.ndarray:
        e, n = frame.to_local(c[:, 0], c[:, 1])
        return np.column_stack([e, n])
    local = shapely.transform(poly, project)
    if not local.is_valid or local.is_empty:
        raise ConfigError("invalid or empty polygon", path=source, key=f"{key}.geometry")
    return local


def field_from_geojson(data: Any, frame: LocalFrame, *, source: str = "<memory>") -> Field:
    """A :class:`Field` from a parsed field file (see the module docstring).

    Raises
    ------
    ConfigError
        Naming ``source`` and ``features[i]``: an unknown role or kind, a bad speed, legs that
        do not join, no boundary, no legs.
    """
    if not isinstance(data, Mapping) or data.get("type") != "FeatureCollection":
        raise ConfigError("a field file must be a GeoJSON FeatureCollection", path=source,
                          key="type")
    features = data.get("features")
    if not isinstance(features, list):
        raise ConfigError("must be an array", path=source, key="features")
    boundary: Polygon | None = None
    work_area: Polygon | None = None
    legs: list[Leg] = []
    for i, feature in enumerate(features):
        key = f"features[{i}]"
        if (not isinstance(feature, Mapping) or feature.get("type") != "Feature"
                or not isinstance(feature.get("properties"), Mapping)):
            raise ConfigError("is not a GeoJSON Feature with properties", path=source, key=key)
        role = feature["properties"].get("role")
        if role == "leg":
            legs.append(_leg_from_feature(feature, frame, source, key))
            if len(legs) > 1:
                gap = float(np.hypot(*(legs[-1].points[0] - legs[-2].points[-1])))
                if gap > JOIN_TOLERANCE_M:
                    raise ConfigError(f"starts {gap:.3f} m from the end of the previous leg",
                                      path=source, key=key)
        elif role in ("boundary", "work_area"):
            if (boundary if role == "boundary" else work_area) is not None:
                raise ConfigError(f"a second {role}", path=source, key=key)
            poly = _polygon_from_feature(feature, frame, source, key)
            if role == "boundary":
                boundary = poly
            else:
                work_area = poly
        else:
            raise ConfigError(f"role {role!r} is not one of boundary, work_area, leg",
                              path=source, key=f"{key}.properties.role")
    if boundary is None:
        raise ConfigError("no feature with role 'boundary'", path=source, key="features")
    if not legs:
        raise ConfigError("no feature with role 'leg'", path=source, key="features")
    return Field(frame, boundary, work_area if work_area is not None else boundary,
                 FieldPath(legs), source)


def load_field(path: str | Path, frame: LocalFrame | None = None) -> Field:
    """Read a field file (GeoJSON) into ``frame`` (share it with the prescription map).

    Without a frame, the field's own is used: centred on the boundary's bounding box.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not JSON, or is not a valid field file.
    """
    source = str(path)
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=source) from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not JSON: {exc.msg} at line {exc.lineno} column {exc.colno}",
                          path=source) from None
    if frame is None:
        frame = _frame_of(data, source)
    return field_from_geojson(data, frame, source=source)


def frame_of_field(data: Any, source: str) -> LocalFrame:
    """The local frame a field file's data is read in (its boundary's bounding box centre)."""
    return _frame_of(data, source)


def _frame_of(data: Any, source: str) -> LocalFrame:
    """The frame centred on the bounding box of the file's boundary feature."""
    for i, feature in enumerate(data.get("features", []) if isinstance(data, Mapping) else []):
        if (isinstance(feature, Mapping) and isinstance(feature.get("properties"), Mapping)
                and feature["properties"].get("role") == "boundary"):
            try:
                coords = shapely.get_coordinates(shape(feature["geometry"]))
                return LocalFrame.centred_on(coords[:, 0], coords[:, 1])
            except (KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:
                raise ConfigError(f"malformed boundary: {exc}", path=source,
                                  key=f"features[{i}].geometry") from None
    raise ConfigError("no feature with role 'boundary'", path=source, key="features")


def _lonlat(geom: Any, frame: LocalFrame) -> Any:
    def unproject(c: np.ndarray) -> np.ndarray:
        lon, lat = frame.to_wgs84(c[:, 0], c[:, 1])
        return np.column_stack([np.round(lon, 9), np.round(lat, 9)])
    return shapely.transform(geom, unproject)


def field_to_geojson(fld: Field) -> dict[str, Any]:
    """The field file of ``fld`` (WGS84, coordinates to 1e-9 degrees = 0.1 mm)."""
    features: list[dict[str, Any]] = [
        {"type": "Feature", "properties": {"role": "boundary"},
         "geometry": mapping(_lonlat(fld.boundary, fld.frame))},
        {"type": "Feature", "properties": {"role": "work_area"},
         "geometry": mapping(_lonlat(fld.work_area, fld.frame))},
    ]
    for leg in fld.path.legs:
        features.append({"type": "Feature",
                         "properties": {"role": "leg", "kind": leg.kind,
                                        "speed_m_s": [leg.v0_m_s, leg.v1_m_s]},
                         "geometry": mapping(_lonlat(LineString(leg.points), fld.frame))})
    data = {"type": "FeatureCollection", "features": features}
    return json.loads(json.dumps(data))  # tuples to lists: plain JSON data


def _arc(cx: float, cy: float, r: float, a0: float, a1: float, n: int) -> np.ndarray:
    ang = np.linspace(a0, a1, n)
    return np.column_stack([cx + r * np.cos(ang), cy + r * np.sin(ang)])


def rectangular_field(frame: LocalFrame, *, boom_width_m: float, passes: int, length_m: float,
                      headland_m: float, overlap_m: float, work_speed_m_s: float,
                      turn_speed_m_s: float, turn_points: int = 13) -> Field:
    """A rectangular field driven in ``passes`` back-and-forth passes plus one overlapping pass.

    The field's south-west corner is the frame's origin; passes run north and south, the first
    one centred half a boom width from the west edge, each next one a boom width further east.
    The last, extra pass (kind ``overlap``) lies ``overlap_m`` west of where a regular pass
    would be, so it re-covers ``overlap_m`` of the previous pass (a field whose width is not a
    multiple of the boom's: the field is ``(passes + 1)·boom_width_m - overlap_m`` wide). The
    work area is the field less a headland of ``headland_m`` at the north and south ends. Each
    pass starts and ends half a headland outside the work area, speeding up from (and slowing
    down to) the turn speed there; the headland turns are semicircles at the turn speed. The
    path starts from rest and stops at the end of the last pass.

    Raises
    ------
    ValueError
        If the numbers do not make a drivable field (the turns must fit in the headland).
    """
    if passes < 1:
        raise ValueError("at least one regular pass")
    if not 0 < overlap_m < boom_width_m:
        raise ValueError("the overlap must be between 0 and the boom width")
    lead = headland_m / 2.0
    if boom_width_m / 2.0 + lead > headland_m or length_m <= 2 * headland_m:
        raise ValueError("the headland must hold the half-boom turn radius and the lead-in, "
                         "and the field be longer than two headlands")
    if min(work_speed_m_s, turn_speed_m_s) <= 0:
        raise ValueError("speeds must be > 0")
    centres = [boom_width_m / 2.0 + i * boom_width_m for i in range(passes)]
    centres.append(centres[-1] + boom_width_m - overlap_m)
    width = centres[-1] + boom_width_m / 2.0
    y_lo, y_hi = headland_m - lead, length_m - headland_m + lead
    legs: list[Leg] = []
    for i, x in enumerate(centres):
        kind = "overlap" if i == len(centres) - 1 else "pass"
        north = i % 2 == 0
        a, b = (y_lo, y_hi) if north else (y_hi, y_lo)
        step = 1.0 if north else -1.0
        start_v = 0.0 if i == 0 else turn_speed_m_s
        legs.append(Leg(kind, np.array([[x, a], [x, a + step * lead]]), start_v, work_speed_m_s))
        legs.append(Leg(kind, np.array([[x, a + step * lead], [x, b - step * lead]]),
                        work_speed_m_s, work_speed_m_s))
        end_v = turn_speed_m_s if i + 1 < len(centres) else 0.0  # the last pass stops
        legs.append(Leg(kind, np.array([[x, b - step * lead], [x, b]]), work_speed_m_s, end_v))
        if i + 1 < len(centres):
            nx = centres[i + 1]
            cx, r = (x + nx) / 2.0, (nx - x) / 2.0
            arc = (_arc(cx, b, r, math.pi, 0.0, turn_points) if north
                   else _arc(cx, b, r, -math.pi, 0.0, turn_points))
            arc[0], arc[-1] = (x, b), (nx, b)
            legs.append(Leg("turn", arc, turn_speed_m_s, turn_speed_m_s))
    boundary = box(0.0, 0.0, width, length_m)
    work_area = box(0.0, headland_m, width, length_m - headland_m)
    return Field(frame, boundary, work_area, FieldPath(legs))
