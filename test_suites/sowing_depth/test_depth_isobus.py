"""Variable-depth seeding under the Task Controller (the depth rig's ``isobus`` suite, issue 42).

The rig plays the tractor (:mod:`plant_emulators.sowing_depth.field_run`): its TC sends the
implement the prescription map's seeding depth (DDI 56) ahead by the set-point latency the
implement's DDOP declares. What is judged is the truth, never what the implement reports (its
DDI 57): every truth cell of the run (one per 10 mm of travel and row), placed where the seed
line was when the planter had travelled that far, on the passes only, and away from the zone
boundaries (the map's depth the same ``BOUNDARY_MARGIN_M`` ahead and behind along the heading),
is compared with the depth of its zone:

* ``isobus.depth.zone_error``: |mean true depth - the zone's depth| per zone;
* ``isobus.depth.zone_pass_rate``: the share of seeds in the zone's GB/T 20865 band (>= 30 mm:
  +-10 mm) per zone.

Limits in ``hil/limits.py``. What is not judged yet, and said so: the zone transition distance,
what happens on TC loss and on speed loss (the reference falls back to its DDOP's default depth,
DDI 58: ``reference_controllers/sowing_depth/isobus_mode.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.isobus.field import load_field, load_prescription
from hil.metrics import depth_statistics
from hil.metrics.depth import qualified_band

pytestmark = pytest.mark.hil_rig("sowing_depth")

#: a cell is judged when the map's depth is its zone's this far ahead and behind it: the
#: transition a controller needs ([D]'s ~1.1 s step response at 6 km/h, 1.8 m) and more
BOUNDARY_MARGIN_M = 3.0


def zone_cells(result) -> tuple[np.ndarray, np.ndarray]:
    """(zone depth per cell, true depths cells x rows) of the judged cells."""
    arrays, _ = result.traces()
    truth = result.truth_arrays()
    run = result.record["truth"]["field_run"]
    field = load_field(run["field"])
    rx = load_prescription(run["prescription"], frame=field.frame)
    distance = arrays["distance_m"]
    moving = np.concatenate([[True], np.diff(distance) > 0.0])
    d, idx = distance[moving], np.flatnonzero(moving)
    cells_d = truth["distance_m"]
    at = idx[np.clip(np.searchsorted(d, cells_d), 0, d.size - 1)]
    east, north = arrays["seed_east_m"][at], arrays["seed_north_m"][at]
    heading = np.radians(arrays["heading_deg"][at])
    on_pass = arrays["on_pass"][at] > 0.5
    zone = np.asarray(rx.rate_at_local(east, north), dtype=float)
    fwd_e, fwd_n = np.sin(heading) * BOUNDARY_MARGIN_M, np.cos(heading) * BOUNDARY_MARGIN_M
    ahead = np.asarray(rx.rate_at_local(east + fwd_e, north + fwd_n), dtype=float)
    behind = np.asarray(rx.rate_at_local(east - fwd_e, north - fwd_n), dtype=float)
    use = on_pass & (zone == ahead) & (zone == behind)
    return zone[use], truth["depth_mm"][use]


@pytest.mark.hil_suite("isobus")
def test_depth_follows_the_map(hil_run, hil_measure) -> None:
    result = hil_run("isobus-depth-field")
    if result.record.get("error"):
        hil_measure("isobus.depth.zone_error", math.nan, run=result,
                    note=str(result.record["error"]))
        return
    zone, depth = zone_cells(result)
    assert zone.size, "no cell of the run lies on a pass away from the zone boundaries"
    for value in sorted(set(zone.tolist())):
        cells = depth[zone == value]
        stats = depth_statistics(cells, value)
        lo, hi = qualified_band(value)
        conditions = {"zone": f"{value:g} mm"}
        note = f"{cells.size} seeds; mean {stats.mean_mm:.2f} mm; band {lo:g}-{hi:g} mm"
        hil_measure("isobus.depth.zone_error", abs(stats.mean_mm - value),
                    conditions=conditions, run=result, note=note)
        hil_measure("isobus.depth.zone_pass_rate", stats.pass_rate_pct,
                    conditions=conditions, run=result, note=note)
