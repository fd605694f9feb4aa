"""Field paths: sampling in time, the speed profile, the generator, the file format."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.errors import ConfigError
from hil.isobus.field import (
    FieldPath,
    Leg,
    LocalFrame,
    field_from_geojson,
    field_to_geojson,
    load_field,
    rectangular_field,
)

FRAME = LocalFrame(116.3, 40.0)


def _field() -> Any:
    return rectangular_field(FRAME, boom_width_m=3.0, passes=3, length_m=50.0, headland_m=6.0,
                             overlap_m=1.5, work_speed_m_s=1.6667, turn_speed_m_s=0.8)


def test_constant_acceleration_leg_positions_and_speeds() -> None:
    path = FieldPath([Leg("pass", np.array([[0.0, 0.0], [0.0, 10.0]]), 0.0, 2.0),
                      Leg("pass", np.array([[0.0, 10.0], [10.0, 10.0]]), 2.0, 2.0)])
    assert path.duration_s == pytest.approx(10.0 + 5.0)   # 10 m at a mean 1 m/s, then 5 s
    p = path.pose(5.0)                                    # s = a t²/2 = 0.2·25/2
    assert (p.east_m, p.north_m, p.speed_m_s, p.heading_deg) == pytest.approx(
        (0.0, 2.5, 1.0, 0.0))
    p = path.pose(12.5)
    assert (p.east_m, p.north_m, p.heading_deg, p.leg, p.kind) == pytest.approx(
        (5.0, 10.0, 90.0, 1, "pass"))
    end = path.pose(100.0)                                 # after the end: standing still
    assert (end.east_m, end.north_m, end.speed_m_s) == (10.0, 10.0, 0.0)


def test_speed_profile_is_the_sampled_speed() -> None:
    path = _field().path
    profile = np.array(path.speed_profile())
    assert np.all(np.diff(profile[:, 0]) > 0)
    t = np.linspace(0.0, path.duration_s - 1e-6, 4001)
    from_profile = np.interp(t, profile[:, 0], profile[:, 1])
    # exact but within the 1 ms steps the profile puts at speed jumps (none in this path)
    assert np.max(np.abs(from_profile - path.sample(t).speed_m_s)) < 1e-6
    # distance integrates the speed
    dense = np.linspace(0.0, path.duration_s, 200_001)
    travelled = np.trapezoid(path.sample(dense).speed_m_s, dense)
    assert travelled == pytest.approx(path.length_m, rel=1e-6)


def test_rectangular_field_layout() -> None:
    fld = _field()
    assert fld.boundary.bounds == pytest.approx((0.0, 0.0, 10.5, 50.0))
    assert fld.work_area.bounds == pytest.approx((0.0, 6.0, 10.5, 44.0))
    kinds = [leg.kind for leg in fld.path.legs]
    assert kinds.count("turn") == 3 and kinds[-1] == "overlap"
    xs = sorted({round(float(leg.points[0, 0]), 6) for leg in fld.path.legs
                 if leg.kind in ("pass", "overlap")})
    assert xs == [1.5, 4.5, 7.5, 9.0]          # the last pass overlaps the previous by 1.5 m
    s = fld.path.sample(np.linspace(0.0, fld.path.duration_s, 2000))
    assert np.all((s.north_m > 0.0) & (s.north_m < 50.0))   # turns stay inside the field
    assert s.speed_m_s[0] == 0.0 and fld.path.pose(fld.path.duration_s).speed_m_s == 0.0
    in_work = (s.north_m > 6.0) & (s.north_m < 44.0)
    assert np.allclose(s.speed_m_s[in_work], 1.6667)        # constant speed over the map


@pytest.mark.parametrize("bad", [dict(headland_m=1.0), dict(overlap_m=3.0), dict(passes=0)])
def test_impossible_fields_are_refused(bad: dict[str, Any]) -> None:
    args: dict[str, Any] = dict(boom_width_m=3.0, passes=3, length_m=50.0, headland_m=6.0,
                                overlap_m=1.5, work_speed_m_s=1.6667, turn_speed_m_s=0.8)
    args.update(bad)
    with pytest.raises(ValueError):
        rectangular_field(FRAME, **args)


def test_file_round_trip(tmp_path: Path) -> None:
    fld = _field()
    path = tmp_path / "field.geojson"
    path.write_text(json.dumps(field_to_geojson(fld)), encoding="utf-8")
    again = load_field(path, FRAME)
    t = np.linspace(0.0, fld.path.duration_s, 500)
    a, b = fld.path.sample(t), again.path.sample(t)
    assert np.max(np.hypot(a.east_m - b.east_m, a.north_m - b.north_m)) < 1e-3
    # coordinates are written to 1e-9 degrees (0.1 mm): a 0.1 mm band along the 100 m edge
    assert again.work_area.symmetric_difference(fld.work_area).area < 0.01
    own = load_field(path)                        # its own frame: centred on the boundary
    assert own.boundary.centroid.distance(own.boundary.centroid.__class__(0, 0)) < 1e-3


def _field_data() -> dict[str, Any]:
    return field_to_geojson(_field())


@pytest.mark.parametrize(("mutate", "key", "words"), [
    (lambda d: d["features"][3]["properties"].update(kind="reverse"),
     r"features\[3\].properties.kind", "reverse"),
    (lambda d: d["features"][3]["properties"].update(speed_m_s="fast"),
     r"features\[3\].properties.speed_m_s", "speed"),
    (lambda d: d["features"][4]["geometry"]["coordinates"].__setitem__(0, [116.31, 40.0]),
     r"features\[4\]", "starts .* m from the end of the previous leg"),
    (lambda d: d["features"][0]["properties"].update(role="fence"),
     r"features\[0\].properties.role", "fence"),
    (lambda d: d["features"].append(dict(d["features"][0])), r"features\[\d+\]",
     "a second boundary"),
    (lambda d: d["features"].pop(0), "features", "no feature with role 'boundary'"),
    (lambda d: d["features"][3]["properties"].update(speed_m_s=[0, 0]), r"features\[3\]",
     "not both 0"),
])
def test_malformed_field_files_name_the_feature(mutate: Any, key: str, words: str) -> None:
    data = _field_data()
    mutate(data)
    with pytest.raises(ConfigError, match=rf"f.geojson: \[{key}\] .*{words}"):
        field_from_geojson(data, FRAME, source="f.geojson")
