"""Boom geometry, coverage and the section on/off rule with look-ahead (TC-SC)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from hil.isobus.field import (
    Boom,
    FieldPath,
    ImplementModel,
    Leg,
    LocalFrame,
    SectionControl,
    dead_reckoning,
    drive_field,
    needed_ground,
    prescription_from_geojson,
    rectangular_field,
)
from hil.isobus.field.coverage import Coverage, swath_quads
from hil.isobus.field.path import Pose
from hil.metrics.application_map import SectionSwitching, section_switching

FRAME = LocalFrame(116.3, 40.0)


def _pose(e: float, n: float, heading: float = 0.0) -> Pose:
    return Pose(0.0, e, n, heading, 1.0, 0.0, 0, "pass")


def test_boom_sections_lie_left_to_right_behind_the_antenna() -> None:
    boom = Boom.uniform(4, 3.0, fore_aft_m=-2.0)
    left, centre, _ = boom.section_lines(10.0, 20.0, 0.0)           # heading north
    assert centre[0, :, 0].tolist() == pytest.approx([8.875, 9.625, 10.375, 11.125])
    assert centre[0, :, 1].tolist() == pytest.approx([18.0] * 4)
    assert left[0, 0].tolist() == pytest.approx([8.5, 18.0])
    _, centre, _ = boom.section_lines(0.0, 0.0, 90.0)                # heading east: left = north
    assert centre[0, 0].tolist() == pytest.approx([-2.0, 1.125])
    assert boom.width_m == pytest.approx(3.0)


def _straight(speed: float = 2.0) -> FieldPath:
    return FieldPath([Leg("pass", np.array([[0.0, 0.0], [0.0, 100.0]]), speed, speed)])


def _first_on_time(sc: SectionControl, path: FieldPath, dt: float = 0.01) -> float:
    for t in np.arange(0.0, path.duration_s, dt):
        if any(sc.update(float(t), path.pose)):
            return float(t)
    raise AssertionError("never switched on")


@pytest.mark.parametrize("turn_on_s", [0.0, 0.5, 1.5])
def test_sections_switch_on_the_declared_look_ahead_before_the_work_area(
        turn_on_s: float) -> None:
    # antenna drives north at 2 m/s, boom 1 m behind, work area starts at y = 20 m: a 50 %
    # rule switches where the section's probe (0.1 m) is half inside, i.e. its line at 19.95 m
    boom = Boom.uniform(4, 3.0, fore_aft_m=-1.0, turn_on_s=turn_on_s)
    sc = SectionControl(boom, box(-10, 20, 10, 80))
    t_on = _first_on_time(sc, _straight())
    line_at_effect = (t_on + turn_on_s) * 2.0 - 1.0
    assert line_at_effect == pytest.approx(19.95, abs=0.021)
    assert all(sc.states)


def test_sections_switch_off_the_turn_off_time_before_the_end() -> None:
    boom = Boom.uniform(2, 3.0, turn_on_s=0.8, turn_off_s=0.3)
    sc = SectionControl(boom, box(-10, 20, 10, 80))
    path = _straight()
    off_at = None
    for t in np.arange(0.0, path.duration_s, 0.01):
        was = sc.states
        now = sc.update(float(t), path.pose)
        if any(was) and not any(now):
            off_at = float(t)
            break
    assert off_at is not None
    assert (off_at + 0.3) * 2.0 == pytest.approx(80.0 - 0.05, abs=0.021)


def _covered_strip(sc: SectionControl, x_min: float, x_max: float) -> None:
    """Lay down the coverage of a one-section pass over x_min..x_max, y 0..50."""
    cov = Coverage(Boom.uniform(1, x_max - x_min))
    for y in np.arange(0.0, 50.01, 0.5):
        cov.record(_pose((x_min + x_max) / 2.0, float(y)), [True])
    cov.record(_pose((x_min + x_max) / 2.0, 50.0), [False])
    cov.boom = sc.boom
    sc.coverage = cov


# sections of a 3 m boom at the antenna: -1.5..-0.75, -0.75..0, 0..0.75, 0.75..1.5 m
@pytest.mark.parametrize(("covered_to", "tolerance", "expected"), [
    (0.0, 0.0, [False, False, True, True]),      # two sections fully covered
    (0.25, 0.0, [False, False, False, True]),    # third section 1/3 covered: 0 % -> off
    (0.25, 50.0, [False, False, True, True]),    # ... 50 % -> on
    (0.5, 50.0, [False, False, False, True]),    # third 2/3 covered: 50 % -> off
    (0.5, 100.0, [False, False, True, True]),    # ... 100 %: on while any of it is fresh
    (1.5, 100.0, [False, False, False, False]),  # all covered: off whatever the tolerance
])
def test_overlap_tolerance(covered_to: float, tolerance: float, expected: list[bool]) -> None:
    sc = SectionControl(Boom.uniform(4, 3.0), box(-10, 0, 10, 100),
                        overlap_tolerance_pct=tolerance)
    _covered_strip(sc, covered_to - 3.0, covered_to)
    assert sc.wanted(_pose(0.0, 25.0)).tolist() == expected


def test_outside_the_work_area_is_never_wanted() -> None:
    sc = SectionControl(Boom.uniform(4, 3.0), box(0, 0, 100, 100))
    # boom straddles the west edge: the two western sections are outside
    assert sc.wanted(_pose(0.0, 50.0)).tolist() == [False, False, True, True]


def test_dead_reckoning_predicts_straight_on() -> None:
    at = dead_reckoning(_pose(1.0, 2.0, 90.0), 2.0, 10.0)
    p = at(11.5)
    assert (p.east_m, p.north_m, p.heading_deg) == pytest.approx((4.0, 2.0, 90.0))


def _example() -> tuple[Any, Boom, Any]:
    fld = rectangular_field(FRAME, boom_width_m=3.0, passes=2, length_m=30.0, headland_m=6.0,
                            overlap_m=1.5, work_speed_m_s=1.6667, turn_speed_m_s=0.8)

    def ll(g: Any) -> Any:
        return shapely.geometry.mapping(shapely.transform(
            g, lambda c: np.column_stack(FRAME.to_wgs84(c[:, 0], c[:, 1]))))
    rx = prescription_from_geojson({
        "type": "FeatureCollection",
        "prescription": {"rate_property": "r", "unit": "kg/ha", "default_rate": 0},
        "features": [{"type": "Feature", "properties": {"r": 200},
                      "geometry": ll(box(0, 0, 10.5, 30))}]}, frame=FRAME)
    return fld, Boom.uniform(4, 3.0, fore_aft_m=-1.0, turn_on_s=0.5, turn_off_s=0.3), rx


def _switching(fld: Any, boom: Boom, rec: Any) -> SectionSwitching:
    a = rec.arrays()
    need = needed_ground(boom, a.east_m, a.north_m, a.heading_deg, a.leg, a.applying,
                         fld.work_area)
    inside = shapely.contains_xy(fld.work_area, a.centre_east_m, a.centre_north_m)
    return section_switching(a.section_distance_m, a.applying, need, inside_work_area=inside)


def rec_coverage(boom: Boom, a: Any) -> Any:
    left, _, right = boom.section_lines(a.east_m, a.north_m, a.heading_deg)
    quads = [swath_quads(left[:, j], right[:, j])[a.applying[:-1, j]]
             for j in range(len(boom.sections))]
    return shapely.union_all(np.concatenate(quads))


def test_a_field_driven_with_section_control_switches_where_it_should() -> None:
    fld, boom, rx = _example()
    rec = drive_field(fld, boom, rx, dt_s=0.1)
    a = rec.arrays()
    legs = [i for i, leg in enumerate(fld.path.legs) if leg.kind == "overlap"]
    on_pass = np.isin(a.leg, legs)[:-1, None] & a.applying[:-1]
    applied_m = np.sum(np.diff(a.section_distance_m, axis=0) * on_pass, axis=0)
    # the overlap pass drives north: its left-hand (west) sections 0, 1 are over pass 2 but
    # for a sliver the previous pass left at the headland (its switch is quantised to one
    # 0.17 m sample); sections 2, 3 apply over the whole 18 m of work area
    assert applied_m[:2].max() < 0.4 and applied_m[2:].min() > 17.8
    # every switch within one sample's travel (1.667 m/s x 0.1 s) of where it should be; the
    # sliver's on/off is the only switch that matches none
    sw = _switching(fld, boom, rec)
    assert len(sw.events) == 20 and sw.worst_error_m <= 0.17   # 2 passes x 4 + 1 x 2, on+off
    assert sw.overlap_m + sw.skip_m < 1.0 and sw.spurious_switches <= 4
    # the coverage is the work area, once: 2 passes + the overlap pass's fresh half
    cov = rec_coverage(boom, a)
    assert cov.area == pytest.approx(fld.work_area.area, rel=0.01)
    assert cov.symmetric_difference(fld.work_area).area < 0.02 * fld.work_area.area


def test_an_implement_slower_than_it_declares_switches_late() -> None:
    # the check can fail: the implement takes twice the turn-on/off time its DDOP declares
    fld, boom, rx = _example()
    rec = drive_field(fld, boom, rx, dt_s=0.1, implement=ImplementModel(switch_delay_scale=2.0))
    sw = _switching(fld, boom, rec)
    assert sw.worst_error_m > 0.4          # 0.5 s late at 1.667 m/s: 0.83 m
    assert sw.headland_skip_m > 4 * 0.4 and sw.headland_overlap_m > 4 * 0.2
