"""A prescription map read from GeoJSON: the application rate at a position (TC-GEO).

The file is an RFC 7946 FeatureCollection of Polygon and MultiPolygon features in WGS84
longitude/latitude, each with a numeric rate property. Which property holds the rate, its unit
and the rate outside every zone are stated in the file's ``prescription`` member or by the
caller (the caller's value wins); a map without a default rate is refused, never read as 0::

    {"type": "FeatureCollection",
     "prescription": {"rate_property": "rate_kg_ha", "unit": "kg/ha", "default_rate": 0},
     "features": [
       {"type": "Feature", "properties": {"name": "low", "rate_kg_ha": 150},
        "geometry": {"type": "Polygon", "coordinates": [[[116.3, 40.0], ...]]}}]}

Zones must not overlap (an overlap larger than ``overlap_tolerance_m2`` is refused with the two
features named); they may share edges. A point on an edge shared by two zones takes the rate
of the zone listed first. Lookups run in a local east/north plane (:mod:`.geodesy`) through a
shapely STRtree, so a 10,000-zone grid map answers as fast as a three-zone one.

Units: ``kg/ha`` (mass per area, ISO 11783-11 DDI 6 in mg/m², resolution 1: 100 raw values
per kg/ha) and ``l/ha`` (volume per area, DDI 1 in mm³/m², resolution 0.01: 10,000 raw values
per l/ha).
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
from shapely.geometry import MultiPolygon, Polygon, shape
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from hil.errors import ConfigError
from hil.isobus.field.geodesy import LocalFrame

__all__ = ["RATE_UNITS", "PrescriptionMap", "RateUnit", "Zone", "load_prescription",
           "prescription_from_geojson"]


@dataclass(frozen=True)
class RateUnit:
    """A map rate unit and the ISO 11783-11 set-point DDI it is sent as."""

    name: str
    ddi: int
    """The set-point DDI (6: mass per area, 1: volume per area)."""
    ddi_per_unit: float
    """Raw DDI values per map unit: 1 kg/ha = 100 mg/m² (DDI 6, resolution 1 mg/m²);
    1 l/ha = 100 mm³/m² = 10,000 raw values of DDI 1 (resolution 0.01 mm³/m²)."""


RATE_UNITS: dict[str, RateUnit] = {
    "kg/ha": RateUnit("kg/ha", 6, 100.0),
    "l/ha": RateUnit("l/ha", 1, 10_000.0),
    # a variable-depth seeding map: DDI 56, set-point seeding depth, 1 mm per raw value
    "mm": RateUnit("mm", 56, 1.0),
}
"""The rate units a map may state."""

_CRS84 = {"urn:ogc:def:crs:OGC:1.3:CRS84", "urn:ogc:def:crs:OGC::CRS84", "EPSG:4326",
          "urn:ogc:def:crs:EPSG::4326"}


@dataclass(frozen=True)
class Zone:
    """One rate zone: a feature of the map."""

    index: int
    """The feature's index in the file's ``features`` array."""
    name: str
    """Its ``name`` property, or ``feature[index]``."""
    rate: float
    """Application rate, in the map's unit."""
    lonlat: Polygon | MultiPolygon
    """The geometry as read, WGS84 degrees."""
    local: Polygon | MultiPolygon
    """The geometry in the map's local frame, m."""


@dataclass(frozen=True)
class PrescriptionMap:
    """Rate zones in a local plane with a default rate outside them.

    Build one with :func:`load_prescription` or :func:`prescription_from_geojson`.
    """

    zones: tuple[Zone, ...]
    default_rate: float
    unit: RateUnit
    rate_property: str
    frame: LocalFrame
    source: str = "<memory>"
    _tree: shapely.STRtree = field(init=False, repr=False, compare=False)
    _rates: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_tree", shapely.STRtree([z.local for z in self.zones]))
        # the zones' rates, then the default (index -1 of a lookup picks it)
        object.__setattr__(self, "_rates",
                           np.array([z.rate for z in self.zones] + [self.default_rate]))

    def zone_index_local(self, east_m: ArrayLike, north_m: ArrayLike) -> np.ndarray:
        """Position in :attr:`zones` of the zone under each plane point, -1 outside all."""
        e, n = np.broadcast_arrays(np.asarray(east_m, dtype=float),
                                   np.asarray(north_m, dtype=float))
        flat_e, flat_n = e.ravel(), n.ravel()
        out = np.full(flat_e.shape, -1, dtype=np.int64)
        if flat_e.size and self.zones:
            points = shapely.points(flat_e, flat_n)
            pairs = self._tree.query(points, predicate="intersects")
            # several hits only on a shared edge: the zone listed first wins (smallest index)
            order = np.lexsort((pairs[1], pairs[0]))
            pts, zs = pairs[0][order], pairs[1][order]
            first = np.ones(pts.shape, dtype=bool)
            first[1:] = pts[1:] != pts[:-1]
            out[pts[first]] = zs[first]
        return out.reshape(e.shape)

    def rate_at_local(self, east_m: ArrayLike, north_m: ArrayLike) -> np.ndarray:
        """Rate (map unit) at plane points (m): the zone's, or the default outside every zone."""
        return self._rates[self.zone_index_local(east_m, north_m)]

    def rate_at(self, lon_deg: ArrayLike, lat_deg: ArrayLike) -> np.ndarray:
        """Rate (map unit) at WGS84 points (degrees)."""
        return self.rate_at_local(*self.frame.to_local(lon_deg, lat_deg))

    def setpoint_ddi_value(self, rate: ArrayLike) -> np.ndarray:
        """Map rates as the raw value of the set-point DDI (:attr:`RateUnit.ddi`), rounded."""
        return np.rint(np.asarray(rate, dtype=float) * self.unit.ddi_per_unit).astype(np.int64)

    @property
    def extent_local(self) -> BaseGeometry:
        """The union of the zones in the local plane."""
        return shapely.union_all([z.local for z in self.zones])


def _fail(source: str, key: str, message: str) -> ConfigError:
    return ConfigError(message, path=source, key=key)


def _number(value: Any, source: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(source, key, f"must be a finite number, got {value!r}")
    if value < 0:
        raise _fail(source, key, f"a rate cannot be negative, got {value!r}")
    return float(value)


def _geometry(feature: Mapping[str, Any], source: str, key: str) -> Polygon | MultiPolygon:
    geom = feature.get("geometry")
    if not isinstance(geom, Mapping) or geom.get("type") not in ("Polygon", "MultiPolygon"):
        kind = geom.get("type") if isinstance(geom, Mapping) else geom
        raise _fail(source, f"{key}.geometry", f"must be a Polygon or MultiPolygon, got {kind!r}")
    try:
        poly = shape(geom)
    except (ValueError, TypeError, AttributeError, IndexError) as exc:
        raise _fail(source, f"{key}.geometry", f"malformed coordinates: {exc}") from None
    if poly.is_empty:
        raise _fail(source, f"{key}.geometry", "is empty")
    coords = shapely.get_coordinates(poly)
    if not np.all(np.isfinite(coords)):
        raise _fail(source, f"{key}.geometry", "has non-finite coordinates")
    if np.any(np.abs(coords[:, 0]) > 180.0) or np.any(np.abs(coords[:, 1]) > 90.0):
        raise _fail(source, f"{key}.geometry",
                    "coordinates are not WGS84 longitude, latitude in degrees (RFC 7946)")
    if not poly.is_valid:
        raise _fail(source, f"{key}.geometry", f"invalid polygon: {explain_validity(poly)}")
    return poly


def _to_local(poly: Polygon | MultiPolygon, frame: LocalFrame) -> Polygon | MultiPolygon:
    def project(coords: np.ndarray) -> np.ndarray:
        e, n = frame.to_local(coords[:, 0], coords[:, 1])
        return np.column_stack([e, n])
    return shapely.transform(poly, project)


def prescription_from_geojson(data: Any, *, source: str = "<memory>",
                              rate_property: str | None = None, unit: str | None = None,
                              default_rate: float | None = None,
                              frame: LocalFrame | None = None,
                              overlap_tolerance_m2: float = 0.01) -> PrescriptionMap:
    """A :class:`PrescriptionMap` from a parsed GeoJSON FeatureCollection.

    Parameters
    ----------
    data : mapping
        The parsed GeoJSON.
    source : str
        What to name in errors (the file).
    rate_property, unit, default_rate : optional
        Override the file's ``prescription`` member; each must be stated by one of the two.
    frame : LocalFrame, optional
        The plane to look up in (share one with the field path); by default the map's own,
        centred on its bounding box.
    overlap_tolerance_m2 : float
        Zones overlapping by more than this area are refused (slivers of GIS rounding pass).

    Raises
    ------
    ConfigError
        Naming ``source`` and the key or ``features[i]``: not a FeatureCollection, a feature
        that is not a polygon or is invalid, a missing or non-numeric rate, an unknown unit, no
        default rate, no features, overlapping zones, a CRS other than WGS84.
    """
    if not isinstance(data, Mapping) or data.get("type") != "FeatureCollection":
        raise _fail(source, "type", "a prescription map must be a GeoJSON FeatureCollection")
    crs = data.get("crs")
    if crs is not None:
        crs_name = crs.get("properties", {}).get("name") if isinstance(crs, Mapping) else crs
        if crs_name not in _CRS84:
            raise _fail(source, "crs", f"must be WGS84 lon/lat (RFC 7946), got {crs_name!r}")
    meta = data.get("prescription", {})
    if not isinstance(meta, Mapping):
        raise _fail(source, "prescription", "must be an object")
    unknown = set(meta) - {"rate_property", "unit", "default_rate"}
    if unknown:
        raise _fail(source, f"prescription.{sorted(unknown)[0]}",
                    "unknown key (expected rate_property, unit, default_rate)")
    rate_property = rate_property if rate_property is not None else meta.get("rate_property")
    unit_name = unit if unit is not None else meta.get("unit")
    if not isinstance(rate_property, str) or not rate_property:
        raise _fail(source, "prescription.rate_property",
                    "no rate property named (in the file or by the caller)")
    if unit_name not in RATE_UNITS:
        raise _fail(source, "prescription.unit",
                    f"unit {unit_name!r} is not one of {', '.join(RATE_UNITS)}")
    if default_rate is None:
        if "default_rate" not in meta:
            raise _fail(source, "prescription.default_rate",
                        "no rate outside the zones stated (in the file or by the caller)")
        default = _number(meta["default_rate"], source, "prescription.default_rate")
    else:
        default = _number(default_rate, source, "default_rate")
    features = data.get("features")
    if not isinstance(features, Sequence) or isinstance(features, (str, bytes)) or not features:
        raise _fail(source, "features", "must be a non-empty array of features")

    read: list[tuple[int, str, float, Polygon | MultiPolygon]] = []
    for i, feature in enumerate(features):
        key = f"features[{i}]"
        if not isinstance(feature, Mapping) or feature.get("type") != "Feature":
            raise _fail(source, key, "is not a GeoJSON Feature")
        props = feature.get("properties")
        if not isinstance(props, Mapping) or rate_property not in props:
            raise _fail(source, f"{key}.properties.{rate_property}", "missing rate")
        rate = _number(props[rate_property], source, f"{key}.properties.{rate_property}")
        name = props.get("name")
        read.append((i, str(name) if name is not None else key, rate,
                     _geometry(feature, source, key)))

    if frame is None:
        bounds = np.array([p.bounds for *_, p in read])
        frame = LocalFrame(float((bounds[:, 0].min() + bounds[:, 2].max()) / 2.0),
                           float((bounds[:, 1].min() + bounds[:, 3].max()) / 2.0))
    zones = tuple(Zone(i, name, rate, poly, _to_local(poly, frame))
                  for i, name, rate, poly in read)
    _refuse_overlaps(zones, source, overlap_tolerance_m2)
    return PrescriptionMap(zones, default, RATE_UNITS[unit_name], rate_property, frame, source)


def _refuse_overlaps(zones: tuple[Zone, ...], source: str, tolerance_m2: float) -> None:
    geoms = [z.local for z in zones]
    tree = shapely.STRtree(geoms)
    left, right = tree.query(geoms, predicate="intersects")
    for a, b in zip(left.tolist(), right.tolist(), strict=True):
        if a >= b:
            continue
        area = geoms[a].intersection(geoms[b]).area
        if area > tolerance_m2:
            za, zb = zones[a], zones[b]
            raise _fail(source, f"features[{za.index}]",
                        f"zone {za.name!r} (features[{za.index}]) overlaps zone {zb.name!r} "
                        f"(features[{zb.index}]) by {area:.3g} m²")


def load_prescription(path: str | Path, **options: Any) -> PrescriptionMap:
    """Read a prescription map file (GeoJSON); ``options`` as :func:`prescription_from_geojson`.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not JSON, or is not a valid prescription map; the
        message names the file (and the key or feature index).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=source) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not JSON: {exc.msg} at line {exc.lineno} column {exc.colno}",
                          path=source) from None
    return prescription_from_geojson(data, source=source, **options)
