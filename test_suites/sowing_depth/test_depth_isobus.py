"""Variable-depth seeding under the Task Controller (the depth rig's ``isobus`` suite, issue 42).

The rig plays the tractor (:mod:`plant_emulators.sowing_depth.field_run`): its TC sends the
implement the prescription map's seeding depth (DDI 56) ahead by the set-point latency the
implement's DDOP declares. What is judged is the truth (:mod:`.isobus_truth`: every truth cell
of the run, one per 10 mm of travel and row, placed where the seed line was when the planter
had travelled that far); the implement's own word (its DDI 57) only where that word is what is
judged:

- ``isobus-depth-field`` (the 3-zone map, 30 / 40 / 35 mm, three passes and an overlap pass):
  per zone, on the passes and away from the zone boundaries (the map's depth the same
  ``BOUNDARY_MARGIN_M`` ahead and behind along the heading), ``isobus.depth.zone_error``
  (|mean true depth - the zone's depth|) and ``isobus.depth.zone_pass_rate`` (the share of
  seeds in the zone depth's GB/T 20865 band); ``isobus.depth.transition_distance``, at each
  zone boundary the seed line crosses on a pass, the longer of how far before it the true depth
  left the old zone's 10 % band and how far after it the depth is within 10 % of the new zone's
  for ``HOLD_M``; ``isobus.depth.reported_error`` per zone (|mean DDI 57
  reported - mean true depth| on the same cells); the rod's travel once the tractor has stopped
  at the end (``isobus.depth.speed_loss.rod_travel``, the TECU reporting 0);
- ``isobus-depth-drive-jammed``: the rod jammed before the 40 mm zone: the reported depth
  against the truth per zone (the seeds stay at ~30 mm while the TC asks for 40, then 35);
- ``isobus-depth-tc-loss`` (40 mm everywhere, the TC lost at 12 s): the time from the TC's
  loss until the true depth stays within 10 % of the default seeding depth the implement's DDOP
  declares (DDI 58), ``isobus.depth.tc_loss.fallback_time``;
- ``isobus-depth-speed-loss``: the TECU falls silent, then the tractor stops: the rod's travel
  while it stands (``isobus.depth.speed_loss.rod_travel``).

Limits and their derivations in ``hil/limits.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.metrics import depth_statistics
from hil.metrics.application_map import transition_distances
from hil.metrics.depth import qualified_band
from hil.rig import RunResult
from test_suites.sowing_depth.isobus_truth import (
    SeedLineTruth,
    early_departure,
    held_entry,
    judged_cells,
    load_run_truth,
    reported_at,
    standstill_rod_travel,
)

pytestmark = [pytest.mark.hil_rig("sowing_depth"), pytest.mark.hil_suite("isobus")]

#: a cell is judged when the map's depth is its zone's this far ahead and behind it: the
#: transition a controller needs ([D]'s ~1.1 s step response at 6 km/h, 1.8 m) and more
BOUNDARY_MARGIN_M = 3.0
#: a depth has reached its new value when the seed line's depth stays within this share of it
#: for HOLD_M of travel: GB/T 20865's tolerance on a field's mean depth (10 % of the target;
#: depth.step.steady_state_error's), which the sensing chain's bias no controller sees stays in
BAND_PCT = 10.0
HOLD_M = 2.0


def _cells(result: RunResult) -> tuple[SeedLineTruth, object]:
    arrays, _ = result.traces()
    return load_run_truth(result.record, arrays, result.truth_arrays())


def _fault_times(result: RunResult, name: str) -> tuple[float, float]:
    """When the run's fault ``name`` was injected and cleared (inf: never cleared)."""
    start, end = math.inf, math.inf
    for event in result.record.get("events", []) or []:
        if name in str(event.get("detail", "")):
            if event.get("kind") == "fault":
                start = float(event["t"])
            elif event.get("kind") == "fault-cleared":
                end = float(event["t"])
    if not math.isfinite(start):
        raise ValueError(f"{result.out_dir}: the run's record has no {name} fault")
    return start, end


def _failed_run(result: RunResult, hil_measure, name: str) -> bool:
    """Record ``name`` as not measured when the run itself failed (the DUT crashed...)."""
    if result.record.get("error"):
        hil_measure(name, math.nan, run=result, note=str(result.record["error"]))
        return True
    return False


# --------------------------------------------------------------------- the field run
def test_depth_follows_the_map(hil_run, hil_measure) -> None:
    result = hil_run("isobus-depth-field")
    if _failed_run(result, hil_measure, "isobus.depth.zone_error"):
        return
    cells, rx = _cells(result)
    use = judged_cells(cells, rx, BOUNDARY_MARGIN_M)
    assert use.any(), "no cell of the run lies on a pass away from the zone boundaries"
    zone, depth = cells.zone_mm[use], cells.depth_mm[use]
    for value in sorted(set(zone.tolist())):
        stats = depth_statistics(depth[zone == value], value)
        lo, hi = qualified_band(value)
        conditions = {"zone": f"{value:g} mm"}
        note = (f"{depth[zone == value].size} seeds; mean {stats.mean_mm:.2f} mm; band "
                f"{lo:g}-{hi:g} mm")
        hil_measure("isobus.depth.zone_error", abs(stats.mean_mm - value),
                    conditions=conditions, run=result, note=note)
        hil_measure("isobus.depth.zone_pass_rate", stats.pass_rate_pct,
                    conditions=conditions, run=result, note=note)


def test_zone_transitions(hil_run, hil_measure) -> None:
    result = hil_run("isobus-depth-field")
    if _failed_run(result, hil_measure, "isobus.depth.transition_distance"):
        return
    cells, _ = _cells(result)
    found = transition_distances(cells.distance_m[:, None], cells.on_pass[:, None],
                                 cells.line_mm[:, None], cells.zone_mm[:, None],
                                 band_pct=BAND_PCT, hold_m=HOLD_M)
    if not found.transitions:
        raise ValueError("isobus-depth-field crossed no zone boundary on a pass")
    line, d = cells.line_mm, cells.distance_m
    changes = np.flatnonzero(cells.zone_mm[1:] != cells.zone_mm[:-1]) + 1
    sides = []
    for t in found.transitions:
        k = int(np.searchsorted(d, t.at_m))
        start = int(changes[changes < k].max()) if np.any(changes < k) else 0
        ok_old = np.abs(line - t.from_rate) <= BAND_PCT / 100.0 * t.from_rate
        sides.append((early_departure(d, ok_old & cells.on_pass, start, k), t.distance_m))
    values = [max(early, late) for early, late in sides]
    worst = int(np.argmax(values))
    t = found.transitions[worst]
    hil_measure("isobus.depth.transition_distance", values[worst], run=result,
                note=f"worst of {len(values)} boundaries: {t.from_rate:g} -> {t.to_rate:g} mm "
                     f"at {t.at_m:.1f} m of travel; (m before, m after) each: "
                     + ", ".join(f"({e:.2f}, {a:.2f})" for e, a in sides))


def _reported_per_zone(result: RunResult, hil_measure, scenario: str) -> None:
    if _failed_run(result, hil_measure, "isobus.depth.reported_error"):
        return
    cells, rx = _cells(result)
    reported = reported_at(cells.t_s, result.record["truth"]["field_run"]["reported_depth"])
    use = judged_cells(cells, rx, BOUNDARY_MARGIN_M) & np.isfinite(reported)
    if not use.any():
        hil_measure("isobus.depth.reported_error", math.inf,
                    conditions={"scenario": scenario, "zone": "all"}, run=result,
                    note="the implement reported no actual seeding depth (DDI 57) on a pass "
                         "away from the zone boundaries")
        return
    for value in sorted(set(cells.zone_mm[use].tolist())):
        here = use & (cells.zone_mm == value)
        said, true = float(reported[here].mean()), float(cells.depth_mm[here].mean())
        hil_measure("isobus.depth.reported_error", abs(said - true),
                    conditions={"scenario": scenario, "zone": f"{value:g} mm"}, run=result,
                    note=f"DDI 57 {said:.2f} mm against the seeds' {true:.2f} mm over "
                         f"{int(here.sum())} cells")


def test_reported_depth_in_the_field(hil_run, hil_measure) -> None:
    _reported_per_zone(hil_run("isobus-depth-field"), hil_measure, "isobus-depth-field")


def test_reported_depth_with_the_drive_jammed(hil_run, hil_measure) -> None:
    _reported_per_zone(hil_run("isobus-depth-drive-jammed"), hil_measure,
                       "isobus-depth-drive-jammed")


# --------------------------------------------------------------------- the TC fails
def test_tc_loss_falls_back_to_the_default_depth(hil_run, hil_measure) -> None:
    result = hil_run("isobus-depth-tc-loss")
    name = "isobus.depth.tc_loss.fallback_time"
    if _failed_run(result, hil_measure, name):
        return
    down, back = _fault_times(result, "tc_down")
    declared = result.record["truth"]["field_run"].get("declared_depth_mm", {})
    if "default" not in declared:
        hil_measure(name, math.inf, run=result,
                    note="the implement's DDOP declares no default seeding depth (DDI 58) "
                         "(or its pool was never active): no depth to fall back to")
        return
    default = float(declared["default"])
    cells, _ = _cells(result)
    after = (cells.t_s >= down) & (cells.t_s < back)
    if not after.any():
        raise ValueError("isobus-depth-tc-loss: the planter sowed nothing while the TC was "
                         "down")
    line = cells.line_mm[after]
    ok = np.abs(line - default) <= BAND_PCT / 100.0 * default
    entry = held_entry(cells.distance_m[after], ok, HOLD_M)
    value = math.inf if entry is None else float(cells.t_s[after][entry] - down)
    hil_measure(name, value, run=result,
                note=(f"the TC lost at {down:g} s; the seeds within {BAND_PCT:g} % of the "
                      f"declared default {default:g} mm from {down + value:.2f} s"
                      if entry is not None else
                      f"the TC lost at {down:g} s; the seeds never stayed within {BAND_PCT:g} %"
                      f" of the declared default {default:g} mm (last {line[-1]:.1f} mm)"))


# --------------------------------------------------------------------- speed lost or zero
def _standstill(result: RunResult, hil_measure, scenario: str) -> None:
    name = "isobus.depth.speed_loss.rod_travel"
    if _failed_run(result, hil_measure, name):
        return
    arrays, _ = result.traces()
    travel, standing_s = standstill_rod_travel(arrays)
    if standing_s <= 0:
        raise ValueError(f"{scenario}: the tractor never stood still after it drove")
    hil_measure(name, travel, conditions={"scenario": scenario}, run=result,
                note=f"{standing_s:.1f} s standing still after the drive")


def test_standstill_at_the_end_of_the_field(hil_run, hil_measure) -> None:
    _standstill(hil_run("isobus-depth-field"), hil_measure, "isobus-depth-field")


def test_standstill_after_the_speed_loss(hil_run, hil_measure) -> None:
    _standstill(hil_run("isobus-depth-speed-loss"), hil_measure, "isobus-depth-speed-loss")
