"""What a depth field run under the Task Controller sowed where, for the report's field maps.

The depth rig records the truth cells of a run (``truth.npz``: one per 10 mm of the planter's
travel, a true seed depth per row) and traces, 100 times a second, where the middle of its seed
line is (``seed_east_m``, ``seed_north_m``, ``heading_deg``) and how far the planter has
travelled (``distance_m``); the run's truth names the seed line's width (``field_run.seed_line``),
the field and the map. Resampled to :data:`hil.isobus.field.laid.SAMPLE_S`, each row is a
section of a :class:`~hil.isobus.field.Boom` across the seed line; what it sowed from one
sample to the next is the mean true depth of its cells in that stretch of travel, over the strip
its seed tube crossed. It sowed wherever the tractor drove a pass or the overlap pass (the
headland turns are left blank, as the fertilizer rig's rows switched off are).

Nothing here reads what the DUT or the TC said: only where the seeds went and how deep.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hil.isobus.field import Boom
from hil.isobus.field.laid import SAMPLE_S, LaidError, field_geometry
from hil.report.field_maps import DEPTH_UNIT, FieldMapError, FieldRunMap

__all__ = ["SOWING_LEGS", "sown_map"]

#: the path's legs on which the planter sows (a headland turn is not sown ground)
SOWING_LEGS = ("pass", "overlap")


def _number(run: Mapping[str, Any], *keys: str) -> float:
    node: Any = run
    for key in keys:
        if not isinstance(node, Mapping) or key not in node:
            raise FieldMapError(f"record.json: truth.field_run.{'.'.join(keys)} missing")
        node = node[key]
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise FieldMapError(f"record.json: truth.field_run.{'.'.join(keys)} is not a number")
    return float(node)


def sown_map(run: Mapping[str, Any], traces: Mapping[str, np.ndarray],
             truth: Mapping[str, np.ndarray] | None) -> FieldRunMap:
    """The :class:`~hil.report.field_maps.FieldRunMap` (``kind`` ``depth``, mm) of a depth
    field run (see the module docstring).

    Raises
    ------
    FieldMapError
        A geometry or file the truth names that cannot be read, a trace or truth array
        missing, or a map that is not a depth map (named).
    """
    width = _number(run, "seed_line", "width_m")
    drive_after = _number(run, "drive_after_s")
    if truth is None or "depth_mm" not in truth or "distance_m" not in truth:
        raise FieldMapError("truth.npz: no depth_mm / distance_m (the run's truth cells)")
    depth = np.asarray(truth["depth_mm"], dtype=float)
    cells_d = np.asarray(truth["distance_m"], dtype=float)
    if depth.ndim != 2 or depth.shape[0] != cells_d.size:
        raise FieldMapError(f"truth.npz: depth_mm {depth.shape} does not match distance_m "
                            f"{cells_d.shape}")
    rows = depth.shape[1]
    try:
        boom = Boom.uniform(rows, width, fore_aft_m=0.0)
        fld, rx = field_geometry(run)
    except (ValueError, LaidError) as exc:
        raise FieldMapError(str(exc)) from None
    if rx is not None and rx.unit.name != DEPTH_UNIT:
        raise FieldMapError(f"{rx.source}: a map in {rx.unit.name}; the depth rig's map is a "
                            f"seeding-depth map ({DEPTH_UNIT})")
    names = ("time_s", "seed_east_m", "seed_north_m", "heading_deg", "distance_m")
    missing = [n for n in names if n not in traces]
    if missing:
        raise FieldMapError(f"traces.npz: no {', '.join(missing)}")
    t_all = np.asarray(traces["time_s"], dtype=float)
    if t_all.size < 2:
        raise FieldMapError("traces.npz: fewer than two samples")
    step = max(1, round(SAMPLE_S / float(np.median(np.diff(t_all)))))
    pick = np.arange(0, t_all.size, step)
    t = t_all[pick]
    east = np.asarray(traces["seed_east_m"], dtype=float)[pick]
    north = np.asarray(traces["seed_north_m"], dtype=float)[pick]
    heading = np.asarray(traces["heading_deg"], dtype=float)[pick]
    travelled = np.asarray(traces["distance_m"], dtype=float)[pick]
    _, centre, _ = boom.section_lines(east, north, heading)
    zeros = np.zeros((1, rows))
    travel = np.vstack([np.linalg.norm(np.diff(centre, axis=0), axis=-1), zeros])
    area = travel * np.array([s.width_m for s in boom.sections])[None, :]
    # each cell to the sample interval [d_k, d_k+1) of the planter's travel it lies in
    k = np.searchsorted(travelled, cells_d, side="right") - 1
    inside = (k >= 0) & (k < t.size - 1)
    sums = np.zeros((t.size, rows))
    counts = np.zeros(t.size)
    np.add.at(sums, k[inside], depth[inside])
    np.add.at(counts, k[inside], 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(counts[:, None] > 0, sums / counts[:, None], 0.0)
    legs = fld.path.sample(np.clip(t - drive_after, 0.0, None)).leg
    sowing = np.array([0 <= int(i) < len(fld.path.legs)
                       and fld.path.legs[int(i)].kind in SOWING_LEGS for i in legs])
    applying = (counts[:, None] > 0) & (area > 0) & sowing[:, None]
    if rx is not None:
        zone = np.asarray(rx.zone_index_local(centre[..., 0], centre[..., 1]))
    else:
        zone = np.full(centre.shape[:2], -1)
    return FieldRunMap(fld, rx, boom, t, east, north, heading, mean * area, area, applying,
                       zone, unit=DEPTH_UNIT, kind="depth")
