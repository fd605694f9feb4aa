"""The depth isobus suite's readings of the truth (test_suites/sowing_depth/isobus_truth.py) on
synthetic runs with known answers: where a seed line's depth reaches a new zone's, the last
reported depth at a time, the rod's travel while standing (fast; the suite's runs against real
controllers are tests/test_discrimination_depth_isobus.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely.geometry import box, mapping

from hil.isobus.field import LocalFrame, prescription_from_geojson
from hil.metrics.application_map import transition_distances
from test_suites.sowing_depth.isobus_truth import (
    early_departure,
    held_entry,
    judged_cells,
    reported_at,
    seed_line_truth,
    smoothed,
    standstill_rod_travel,
)

FRAME = LocalFrame(116.3, 40.0)
BOUNDARY_M = 20.0


def _map() -> object:
    """30 mm south of y = 20 m, 40 mm north, over a 4 m x 40 m strip."""
    def lonlat(geom: object) -> object:
        return mapping(shapely.transform(geom, lambda c: np.column_stack(
            FRAME.to_wgs84(c[:, 0], c[:, 1]))))

    return prescription_from_geojson({
        "type": "FeatureCollection",
        "prescription": {"rate_property": "d", "unit": "mm", "default_rate": 35.0},
        "features": [
            {"type": "Feature", "properties": {"d": 30.0}, "geometry": lonlat(box(-2, 0, 2, 20))},
            {"type": "Feature", "properties": {"d": 40.0},
             "geometry": lonlat(box(-2, 20, 2, 40))}]}, frame=FRAME)


def _run(late_m: float, rows: int = 3) -> tuple[dict, dict]:
    """A pass north along x = 0 at 2 m/s from y = 0 to 40 m; the seeds reach the 40 mm zone's
    depth ``late_m`` after its boundary (a 10 mm step)."""
    t = np.arange(0.0, 20.0, 0.01)
    y = 2.0 * t
    traces = {"time_s": t, "distance_m": y, "seed_east_m": np.zeros_like(t), "seed_north_m": y,
              "heading_deg": np.zeros_like(t), "on_pass": np.ones_like(t)}
    cells = np.arange(0.005, 40.0, 0.01)
    depth = np.where(cells < BOUNDARY_M + late_m, 30.0, 40.0)
    rng = np.random.default_rng(1)
    truth = {"distance_m": cells,
             "depth_mm": depth[:, None] + rng.normal(0.0, 1.0, (cells.size, rows))}
    return traces, truth


@pytest.mark.parametrize("late_m", [0.0, 1.5, 4.0])
def test_the_transition_ends_where_the_seeds_reach_the_new_depth(late_m: float) -> None:
    traces, truth = _run(late_m)
    cells = seed_line_truth(traces, truth, _map())
    found = transition_distances(cells.distance_m[:, None], cells.on_pass[:, None],
                                 cells.line_mm[:, None], cells.zone_mm[:, None],
                                 band_pct=10.0, hold_m=2.0)
    assert len(found.transitions) == 1
    # the seed line's depth, smoothed over 0.5 m (centred), is in the 36-44 mm band once
    # 60 % of its window is past the step: 0.05 m after it
    assert late_m <= found.transitions[0].distance_m <= late_m + 0.1


@pytest.mark.parametrize("early_m", [0.0, 2.0])
def test_a_depth_that_changes_early_leaves_the_old_zone_before_the_boundary(
        early_m: float) -> None:
    traces, truth = _run(late_m=-early_m)
    cells = seed_line_truth(traces, truth, _map())
    k = int(np.flatnonzero(np.diff(cells.zone_mm) != 0)[0]) + 1
    ok_old = np.abs(cells.line_mm - 30.0) <= 3.0
    early = early_departure(cells.distance_m, ok_old, 0, k)
    # the smoothed line leaves 27-33 mm once 30 % of its 0.5 m window is past the step:
    # 0.1 m before it
    assert early_m + 0.08 <= early <= early_m + 0.12


def test_a_depth_that_never_comes_is_an_infinite_transition() -> None:
    traces, truth = _run(late_m=100.0)
    cells = seed_line_truth(traces, truth, _map())
    found = transition_distances(cells.distance_m[:, None], cells.on_pass[:, None],
                                 cells.line_mm[:, None], cells.zone_mm[:, None],
                                 band_pct=10.0, hold_m=2.0)
    assert [t.distance_m for t in found.transitions] == [math.inf]


def test_judged_cells_keep_away_from_the_boundary() -> None:
    traces, truth = _run(late_m=0.0)
    cells = seed_line_truth(traces, truth, _map())
    use = judged_cells(cells, _map(), 3.0)
    d = cells.distance_m[use]
    assert not np.any((d > BOUNDARY_M - 3.0 + 0.01) & (d < BOUNDARY_M + 3.0 - 0.01))
    # the strip's ends are boundaries too (the map's 35 mm outside its zones)
    assert 3.0 <= d.min() < 3.1 and 36.9 < d.max() <= 37.0


def test_held_entry_and_smoothing() -> None:
    d = np.arange(10) * 1.0
    ok = np.array([1, 0, 1, 1, 0, 1, 1, 1, 1, 0], dtype=bool)
    assert held_entry(d, ok, 2.0) == 5
    assert held_entry(d, ok, 10.0) is None
    assert held_entry(d[:9], ok[:9], 10.0) == 5          # to the end of a shorter stretch
    assert np.allclose(smoothed(np.full(7, 3.0), 4), 3.0)
    assert np.allclose(smoothed(np.arange(5.0), 3)[1:-1], [1.0, 2.0, 3.0])


def test_the_reported_depth_holds_until_the_next_report() -> None:
    reported = {"t_s": [1.0, 2.0, 5.0], "depth_mm": [30.0, 33.0, 40.0]}
    got = reported_at(np.array([0.5, 1.0, 1.9, 2.0, 4.99, 6.0]), reported)
    assert np.isnan(got[0]) and got[1:].tolist() == [30.0, 30.0, 33.0, 33.0, 40.0]
    assert np.isnan(reported_at(np.array([1.0]), {"t_s": [], "depth_mm": []})).all()


def test_rod_travel_counts_only_standing_after_the_drive() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    speed = np.where((t >= 2.0) & (t < 6.0), 1.0, 0.0)     # stands, drives, stands
    rod = np.where(t < 2.0, 0.5 * t, 1.0)                   # moved 1 mm before the drive
    rod = rod + np.where(t >= 7.0, 0.3 * (t - 7.0), 0.0)   # and 0.9 mm after the stop
    travel, standing = standstill_rod_travel({"time_s": t, "ground_speed_mps": speed,
                                              "rod_position_mm": rod})
    assert travel == pytest.approx(0.9, abs=0.01) and standing == pytest.approx(4.0, abs=0.02)
