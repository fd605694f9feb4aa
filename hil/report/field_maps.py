"""What a field run under the Task Controller laid where, read for the report from the run's
own files: the traces (the antenna's pose, each row's delivered mass) and the truth's
``field_run`` (the openers' geometry, the field file, the prescription map).

The report must not import the suites, so this is computed here, the way the ``isobus``
suite's truth (``test_suites/fertilizer/field_truth.py``) computes it, with the
:mod:`hil.isobus.field` helpers: resampled to :data:`SAMPLE_S`, each row is a section of a
:class:`~hil.isobus.field.Boom` whose opener sweeps a strip; what a row laid from one sample to
the next is the mass delivered meanwhile over the strip it crossed (``10 x g / m²`` = kg/ha),
and it applied at all when that is at least :data:`APPLYING_SHARE` of the map's smallest
non-zero rate (a row switched off lays nothing). The as-applied map is
:class:`~hil.isobus.field.AsAppliedRecord`'s: one polygon per row per :data:`CELL_LENGTH_M` of
travel, with the mass laid over its area as its rate, in WGS84 (RFC 7946).

Nothing here reads what the DUT or the TC said: only the mass that landed and where.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import shapely
from shapely.geometry import mapping, shape
from shapely.geometry.base import BaseGeometry

from hil.errors import ConfigError
from hil.isobus.field import (
    AsAppliedRecord,
    Boom,
    Field,
    PrescriptionMap,
    load_field,
    load_prescription,
)

#: the sample period of the map, as the suite's truth (at 6 km/h, 17 cm of travel)
SAMPLE_S = 0.1
#: a row applies when it lays at least this share of the map's smallest non-zero rate (the
#: suite's rule: a row switched off lays nothing, one on lays its rate +-15 %)
APPLYING_SHARE = 0.5
#: without a non-zero rate in the map, a row applies above this (kg/ha)
APPLYING_FLOOR_KG_HA = 1.0
#: each row strip of the as-applied map is cut every this much travel (m)
CELL_LENGTH_M = 1.0
#: the unit of what the rig lays (mass per area)
UNIT = "kg/ha"


class FieldMapError(ValueError):
    """The run's field-run data cannot be read (the message names the file or key)."""


def is_field_run(record: Mapping[str, Any]) -> bool:
    """Whether a run's ``record.json`` is a field run under the TC (``truth.field_run``)."""
    truth = record.get("truth")
    return isinstance(truth, Mapping) and isinstance(truth.get("field_run"), Mapping)


@dataclass(frozen=True)
class ZoneRate:
    """What the map prescribes in one zone and what the rows laid there."""

    index: int
    """The zone's position in the map (-1: the ground outside every zone)."""
    name: str
    prescribed: float
    laid: float | None
    """Mass laid over the ground the rows applied on in the zone (kg/ha); None: none."""
    area_m2: float
    """The ground the rows applied on in the zone."""


@dataclass(frozen=True)
class FieldRunMap:
    """One field run, sampled at :data:`SAMPLE_S`: ``k`` samples, ``s`` rows."""

    field: Field
    prescription: PrescriptionMap | None
    boom: Boom
    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    mass_g: np.ndarray
    """(k, s) mass a row laid from sample k to k+1 (0 at the last sample)."""
    area_m2: np.ndarray
    """(k, s) the strip its opener crossed meanwhile."""
    applying: np.ndarray
    """(k, s) the row applied from sample k to k+1."""
    zone: np.ndarray
    """(k, s) the map's zone under the opener at sample k (-1: outside every zone)."""

    @property
    def rate(self) -> np.ndarray:
        """(k, s) kg/ha laid from sample k to k+1 (0 where the row did not apply)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = np.where(self.area_m2 > 0, 10.0 * self.mass_g / self.area_m2, 0.0)
        return np.where(self.applying, rate, 0.0)

    @cached_property
    def as_applied(self) -> AsAppliedRecord:
        """The samples as an :class:`~hil.isobus.field.AsAppliedRecord` (its map's writer)."""
        record = AsAppliedRecord(self.boom, self.field.frame, UNIT)
        rate = self.rate
        for k in range(self.t_s.size):
            pose = SimpleNamespace(t_s=self.t_s[k], east_m=self.east_m[k],
                                   north_m=self.north_m[k], heading_deg=self.heading_deg[k])
            record.add(pose, self.applying[k], rate[k])
        return record

    @cached_property
    def geojson(self) -> dict[str, Any]:
        """The as-applied map: an RFC 7946 FeatureCollection in WGS84, one feature per row
        strip segment (at most :data:`CELL_LENGTH_M` long) with the rate laid on it.

        :meth:`AsAppliedRecord.to_geojson`'s features, with ``row`` (1 = leftmost) added and
        the rings wound as RFC 7946 says (exterior counter-clockwise)."""
        if not self.applying[:-1].any():
            return {"type": "FeatureCollection", "features": []}
        data = self.as_applied.to_geojson(cell_length_m=CELL_LENGTH_M)
        for feature in data["features"]:
            feature["properties"]["row"] = int(feature["properties"]["section"]) + 1
            oriented = shapely.orient_polygons(shape(feature["geometry"]))
            feature["geometry"] = json.loads(json.dumps(mapping(oriented)))
        return data

    def strips_local(self) -> list[tuple[BaseGeometry, float]]:
        """The as-applied map's polygons in the field's plane (m) with their rates."""
        frame = self.field.frame

        def project(c: np.ndarray) -> np.ndarray:
            e, n = frame.to_local(c[:, 0], c[:, 1])
            return np.column_stack([e, n])

        features = self.geojson["features"]
        lonlat = np.array([shape(f["geometry"]) for f in features], dtype=object)
        local = shapely.transform(lonlat, project) if features else lonlat   # one projection
        return [(geom, float(f["properties"]["rate"]))
                for geom, f in zip(local, features, strict=True)]

    def zone_rates(self) -> list[ZoneRate]:
        """Per zone of the map, then the ground outside every zone where rows applied."""
        zones = self.prescription.zones if self.prescription is not None else ()
        out = []
        for i, z in enumerate(zones):
            out.append(self._zone_rate(i, z.name, z.rate))
        if self.prescription is not None:
            outside = self._zone_rate(-1, "outside every zone", self.prescription.default_rate)
            if outside.area_m2 > 0:
                out.append(outside)
        return out

    def _zone_rate(self, index: int, name: str, prescribed: float) -> ZoneRate:
        on = self.applying & (self.zone == index)
        area = float(self.area_m2[on].sum())
        laid = 10.0 * float(self.mass_g[on].sum()) / area if area > 0 else None
        return ZoneRate(index, name, prescribed, laid, area)

    def save_geojson(self, path: Path) -> None:
        """Write :attr:`geojson` to ``path``."""
        Path(path).write_text(json.dumps(self.geojson) + "\n", encoding="utf-8")


def _number(run: Mapping[str, Any], *keys: str) -> float:
    node: Any = run
    for key in keys:
        if not isinstance(node, Mapping) or key not in node:
            raise FieldMapError(f"record.json: truth.field_run.{'.'.join(keys)} missing")
        node = node[key]
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise FieldMapError(f"record.json: truth.field_run.{'.'.join(keys)} is not a number")
    return float(node)


def _load_geometry(run: Mapping[str, Any]) -> tuple[Field, PrescriptionMap | None]:
    field_file = run.get("field")
    if not isinstance(field_file, str) or not field_file:
        raise FieldMapError("record.json: truth.field_run.field names no field file")
    rx_file = run.get("prescription")
    try:
        fld = load_field(field_file)
        rx = load_prescription(rx_file, frame=fld.frame) if rx_file else None
    except ConfigError as exc:
        raise FieldMapError(f"the run's field or map cannot be read: {exc}") from None
    if rx is not None and rx.unit.name != UNIT:
        raise FieldMapError(f"{rx_file}: a map in {rx.unit.name}; the rig lays mass ({UNIT})")
    return fld, rx


def field_run_map(record: Mapping[str, Any], traces: Mapping[str, np.ndarray]) -> FieldRunMap:
    """A run's :class:`FieldRunMap` from its ``record.json`` and ``traces.npz``.

    Raises
    ------
    FieldMapError
        Not a field run, a geometry or file the truth names that cannot be read, or a trace
        missing (naming it).
    """
    if not is_field_run(record):
        raise FieldMapError("record.json: no truth.field_run (not a field run under a TC)")
    run = record["truth"]["field_run"]
    rows = int(_number(run, "boom", "rows"))
    try:
        boom = Boom.uniform(rows, _number(run, "boom", "width_m"),
                            fore_aft_m=_number(run, "boom", "opener_offset_m"))
    except ValueError as exc:
        raise FieldMapError(f"record.json: truth.field_run.boom: {exc}") from None
    fld, rx = _load_geometry(run)
    names = ["time_s", "east_m", "north_m", "heading_deg",
             *(f"delivered_{r + 1}_g" for r in range(rows))]
    missing = [n for n in names if n not in traces]
    if missing:
        raise FieldMapError(f"traces.npz: no {', '.join(missing)}")
    t_all = np.asarray(traces["time_s"], dtype=float)
    if t_all.size < 2:
        raise FieldMapError("traces.npz: fewer than two samples")
    step = max(1, round(SAMPLE_S / float(np.median(np.diff(t_all)))))
    pick = np.arange(0, t_all.size, step)
    east = np.asarray(traces["east_m"], dtype=float)[pick]
    north = np.asarray(traces["north_m"], dtype=float)[pick]
    heading = np.asarray(traces["heading_deg"], dtype=float)[pick]
    _, centre, _ = boom.section_lines(east, north, heading)
    travel = np.linalg.norm(np.diff(centre, axis=0), axis=-1)               # (k-1, s)
    delivered = np.column_stack([np.asarray(traces[f"delivered_{r + 1}_g"], dtype=float)[pick]
                                 for r in range(rows)])
    zeros = np.zeros((1, rows))
    mass = np.vstack([np.diff(delivered, axis=0), zeros])
    width = np.array([s.width_m for s in boom.sections])
    area = np.vstack([travel, zeros]) * width[None, :]
    if rx is not None:
        zone = rx.zone_index_local(centre[..., 0], centre[..., 1])
        floor = min((z.rate for z in rx.zones if z.rate > 0), default=0.0)
    else:
        zone = np.full(centre.shape[:2], -1)
        floor = 0.0
    threshold = APPLYING_SHARE * floor if floor > 0 else APPLYING_FLOOR_KG_HA
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.where(area > 0, 10.0 * mass / area, 0.0)
    applying = (area > 0) & (rate >= threshold)
    return FieldRunMap(fld, rx, boom, t_all[pick], east, north, heading, mass, area, applying,
                       np.asarray(zone))
