"""What a field run under the Task Controller laid or sowed where, for the report: the maps and
the as-applied GeoJSON.

- the fertilizer rig (``truth.field_run.boom``): drawn from
  :func:`hil.isobus.field.laid.laid_from_run` (the same reading of the run's traces and truth as
  the ``isobus`` suite judges), each row's mass laid over its area as its rate (kg/ha);
- the depth rig (``truth.field_run.seed_line``): drawn from the run's truth cells
  (:mod:`hil.report.field_depth`), each row's true seeding depth (mm).

The as-applied map is :class:`~hil.isobus.field.AsAppliedRecord`'s: one polygon per row per
:data:`CELL_LENGTH_M` of travel, with its value as its ``rate``, in WGS84 (RFC 7946).

Nothing here reads what the DUT or the TC said: only what landed and where.
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

from hil.isobus.field import (
    AsAppliedRecord,
    Boom,
    Field,
    PrescriptionMap,
)
from hil.isobus.field.laid import LaidError, laid_from_run

#: each row strip of the as-applied map is cut every this much travel (m)
CELL_LENGTH_M = 1.0
#: the unit of what the fertilizer rig lays (mass per area)
UNIT = "kg/ha"
#: the unit of the depth rig's seeding depth
DEPTH_UNIT = "mm"


class FieldMapError(ValueError):
    """The run's field-run data cannot be read (the message names the file or key)."""


def is_field_run(record: Mapping[str, Any]) -> bool:
    """Whether a run's ``record.json`` is a field run under the TC (``truth.field_run``)."""
    truth = record.get("truth")
    return isinstance(truth, Mapping) and isinstance(truth.get("field_run"), Mapping)


@dataclass(frozen=True)
class ZoneRate:
    """What the map prescribes in one zone and what the rows laid (or sowed) there."""

    index: int
    """The zone's position in the map (-1: the ground outside every zone)."""
    name: str
    prescribed: float
    laid: float | None
    """Mass laid over the ground the rows applied on in the zone (kg/ha), or the mean depth
    sown there (mm); None: none."""
    area_m2: float
    """The ground the rows applied on in the zone."""


@dataclass(frozen=True)
class FieldRunMap:
    """One field run, sampled at :data:`hil.isobus.field.laid.SAMPLE_S`: ``k`` samples, ``s``
    rows. ``kind`` ``rate``: what the rows laid (``unit`` kg/ha); ``depth``: the seeding depth
    they sowed (``unit`` mm)."""

    field: Field
    prescription: PrescriptionMap | None
    boom: Boom
    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    amount: np.ndarray
    """(k, s) the value times the ground it covers, from sample k to k+1 (0 at the last
    sample): kg/ha x m² (10 x the mass laid, g) for a rate, mm x m² for a depth."""
    area_m2: np.ndarray
    """(k, s) the strip its opener crossed meanwhile."""
    applying: np.ndarray
    """(k, s) the row applied (sowed) from sample k to k+1."""
    zone: np.ndarray
    """(k, s) the map's zone under the opener at sample k (-1: outside every zone)."""
    unit: str = UNIT
    kind: str = "rate"

    @property
    def rate(self) -> np.ndarray:
        """(k, s) the value from sample k to k+1 (kg/ha laid, or mm sown; 0 where the row did
        not apply)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = np.where(self.area_m2 > 0, self.amount / self.area_m2, 0.0)
        return np.where(self.applying, rate, 0.0)

    @cached_property
    def as_applied(self) -> AsAppliedRecord:
        """The samples as an :class:`~hil.isobus.field.AsAppliedRecord` (its map's writer)."""
        record = AsAppliedRecord(self.boom, self.field.frame, self.unit)
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

        :meth:`AsAppliedRecord.to_geojson`'s features, with ``row`` (1 = leftmost) added (and,
        for a depth, ``depth_mm``, the same as ``rate``) and the rings wound as RFC 7946 says
        (exterior counter-clockwise)."""
        if not self.applying[:-1].any():
            return {"type": "FeatureCollection", "features": []}
        data = self.as_applied.to_geojson(cell_length_m=CELL_LENGTH_M)
        for feature in data["features"]:
            feature["properties"]["row"] = int(feature["properties"]["section"]) + 1
            if self.kind == "depth":
                feature["properties"]["depth_mm"] = feature["properties"]["rate"]
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
        laid = float(self.amount[on].sum()) / area if area > 0 else None
        return ZoneRate(index, name, prescribed, laid, area)

    def save_geojson(self, path: Path) -> None:
        """Write :attr:`geojson` to ``path``."""
        Path(path).write_text(json.dumps(self.geojson) + "\n", encoding="utf-8")


def field_run_map(record: Mapping[str, Any], traces: Mapping[str, np.ndarray],
                  truth: Mapping[str, np.ndarray] | None = None) -> FieldRunMap:
    """A run's :class:`FieldRunMap` from its ``record.json``, ``traces.npz`` and (a depth run)
    ``truth.npz``.

    Raises
    ------
    FieldMapError
        Not a field run, a geometry or file the truth names that cannot be read, or a trace
        or truth array missing (naming it).
    """
    if not is_field_run(record):
        raise FieldMapError("record.json: no truth.field_run (not a field run under a TC)")
    run = record["truth"]["field_run"]
    if "seed_line" in run:
        from hil.report.field_depth import sown_map

        return sown_map(run, traces, truth)
    try:
        laid = laid_from_run(run, traces)
    except LaidError as exc:
        raise FieldMapError(str(exc)) from None
    rx = laid.prescription
    if rx is not None and rx.unit.name != UNIT:
        raise FieldMapError(f"{rx.source}: a map in {rx.unit.name}; the rig lays mass ({UNIT})")
    return FieldRunMap(laid.field, rx, laid.boom, laid.t_s, laid.east_m, laid.north_m,
                       laid.heading_deg, 10.0 * laid.mass_g, laid.area_m2, laid.applying,
                       laid.zone)
