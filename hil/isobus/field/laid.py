"""What a field run really laid where: the rows' delivered mass placed on the ground.

One reading of a recorded field run under the Task Controller (a scenario with a ``[tractor]``
table), used by the ``isobus`` suite's truth (``test_suites/fertilizer/field_truth.py``) and by
the report's field maps (:mod:`hil.report.field_maps`), so both judge and draw the same thing.
The rig records, 100 times a second, the antenna's pose (``east_m``, ``north_m``,
``heading_deg``) and each row's delivered mass (``delivered_<row>_g``: what has left the tube at
the furrow opener); the run's truth names the openers' geometry (``field_run.boom``), the field
and the map. Resampled to :data:`SAMPLE_S`, each row is a section of a
:class:`~hil.isobus.field.Boom` whose opener sweeps a strip:

- what it laid from one sample to the next is the mass delivered meanwhile over the strip it
  crossed (``10 x g / m²`` = kg/ha);
- it applied at all when that is at least :data:`APPLYING_SHARE` of the map's smallest non-zero
  rate: a row switched off lays nothing (its clutch stops the roller), one switched on lays its
  target with the flutes' +-15 % pulsation, so half the smallest rate splits them cleanly.

Nothing here reads what the DUT or the TC said: only the mass that landed and where.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.errors import ConfigError
from hil.isobus.field.boom import Boom
from hil.isobus.field.path import Field, field_from_geojson, frame_of_field, load_field
from hil.isobus.field.prescription import (
    PrescriptionMap,
    load_prescription,
    prescription_from_geojson,
)

__all__ = ["APPLYING_FLOOR_KG_HA", "APPLYING_SHARE", "SAMPLE_S", "Laid", "LaidError",
           "field_geometry", "laid_from_run"]

#: the sample period: 1/10 of the control period would be finer than the openers' own spread;
#: at 6 km/h a sample is 17 cm of travel
SAMPLE_S = 0.1
#: a row applies when it lays at least this share of the map's smallest non-zero rate
APPLYING_SHARE = 0.5
#: without a non-zero rate in the map, a row applies above this (kg/ha)
APPLYING_FLOOR_KG_HA = 1.0


class LaidError(ValueError):
    """The run's field-run data cannot be read (the message names the file, key or trace)."""


@dataclass(frozen=True)
class Laid:
    """One field run at :data:`SAMPLE_S`: ``k`` samples, ``s`` rows (interval k -> k+1)."""

    boom: Boom
    field: Field
    prescription: PrescriptionMap | None
    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    heading_deg: np.ndarray
    centre: np.ndarray
    """(k, s, 2) each opener on the ground."""
    travel_m: np.ndarray
    """(k, s) how far each opener moves from sample k to k+1 (0 at the last sample)."""
    mass_g: np.ndarray
    """(k, s) mass a row laid from sample k to k+1 (0 at the last sample)."""
    area_m2: np.ndarray
    """(k, s) the strip its opener crossed meanwhile."""
    rate: np.ndarray
    """(k, s) kg/ha laid from sample k to k+1 (0 where the opener did not move)."""
    applying: np.ndarray
    """(k, s) the row applied from sample k to k+1."""
    zone: np.ndarray
    """(k, s) the map's zone under the opener (-1: outside every zone, or no map)."""

    @property
    def width_m(self) -> np.ndarray:
        """(s,) the rows' strip widths."""
        return np.array([s.width_m for s in self.boom.sections])


def _number(run: Mapping[str, Any], *keys: str) -> float:
    node: Any = run
    for key in keys:
        if not isinstance(node, Mapping) or key not in node:
            raise LaidError(f"record.json: truth.field_run.{'.'.join(keys)} missing")
        node = node[key]
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise LaidError(f"record.json: truth.field_run.{'.'.join(keys)} is not a number")
    return float(node)


def field_geometry(run: Mapping[str, Any]) -> tuple[Field, PrescriptionMap | None]:
    """The field and the map of a field run: as the record holds them (``field_geojson``,
    ``prescription_geojson``: a record read elsewhere still has them), else from the files it
    names.

    Raises
    ------
    LaidError
        Neither can be read (naming the key or the file).
    """
    field_file = run.get("field")
    if not isinstance(field_file, str) or not field_file:
        raise LaidError("record.json: truth.field_run.field names no field file")
    rx_file = run.get("prescription")
    try:
        if "field_geojson" in run:
            fld = field_from_geojson(run["field_geojson"], frame_of_field(run["field_geojson"],
                                                                          field_file),
                                     source=f"{field_file} (as recorded)")
        else:
            fld = load_field(field_file)
        if not rx_file:
            rx = None
        elif "prescription_geojson" in run:
            rx = prescription_from_geojson(run["prescription_geojson"], frame=fld.frame,
                                           source=f"{rx_file} (as recorded)")
        else:
            rx = load_prescription(rx_file, frame=fld.frame)
    except ConfigError as exc:
        raise LaidError(f"the run's field or map cannot be read: {exc}") from None
    return fld, rx


def laid_from_run(run: Mapping[str, Any], traces: Mapping[str, np.ndarray]) -> Laid:
    """What the run's rows laid where (see the module docstring).

    Parameters
    ----------
    run : mapping
        The run record's ``truth.field_run``.
    traces : mapping
        The run's traces (``traces.npz``).

    Raises
    ------
    LaidError
        A geometry or file the truth names that cannot be read, or a trace missing (named).
    """
    rows = int(_number(run, "boom", "rows"))
    try:
        boom = Boom.uniform(rows, _number(run, "boom", "width_m"),
                            fore_aft_m=_number(run, "boom", "opener_offset_m"))
    except ValueError as exc:
        raise LaidError(f"record.json: truth.field_run.boom: {exc}") from None
    fld, rx = field_geometry(run)
    names = ["time_s", "east_m", "north_m", "heading_deg",
             *(f"delivered_{r + 1}_g" for r in range(rows))]
    missing = [n for n in names if n not in traces]
    if missing:
        raise LaidError(f"traces.npz: no {', '.join(missing)}")
    t_all = np.asarray(traces["time_s"], dtype=float)
    if t_all.size < 2:
        raise LaidError("traces.npz: fewer than two samples")
    step = max(1, round(SAMPLE_S / float(np.median(np.diff(t_all)))))
    pick = np.arange(0, t_all.size, step)
    east = np.asarray(traces["east_m"], dtype=float)[pick]
    north = np.asarray(traces["north_m"], dtype=float)[pick]
    heading = np.asarray(traces["heading_deg"], dtype=float)[pick]
    _, centre, _ = boom.section_lines(east, north, heading)
    zeros = np.zeros((1, rows))
    travel = np.vstack([np.linalg.norm(np.diff(centre, axis=0), axis=-1), zeros])
    delivered = np.column_stack([np.asarray(traces[f"delivered_{r + 1}_g"], dtype=float)[pick]
                                 for r in range(rows)])
    mass = np.vstack([np.diff(delivered, axis=0), zeros])
    width = np.array([s.width_m for s in boom.sections])
    area = travel * width[None, :]
    if rx is not None:
        zone = np.asarray(rx.zone_index_local(centre[..., 0], centre[..., 1]))
        floor = min((z.rate for z in rx.zones if z.rate > 0), default=0.0)
    else:
        zone = np.full(centre.shape[:2], -1)
        floor = 0.0
    threshold = APPLYING_SHARE * floor if floor > 0 else APPLYING_FLOOR_KG_HA
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.where(area > 0, 10.0 * mass / area, 0.0)
    applying = (area > 0) & (rate >= threshold)
    return Laid(boom, fld, rx, t_all[pick], east, north, heading, centre, travel, mass, area,
                rate, applying, zone)
