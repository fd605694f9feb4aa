"""The as-applied record and map: arrays for the metrics, GeoJSON a GIS tool reads."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import box, shape

from hil.isobus.field import AsAppliedRecord, Boom, LocalFrame
from hil.isobus.field.path import Pose

FRAME = LocalFrame(116.3, 40.0)


def _record() -> AsAppliedRecord:
    """Two sections drive north 0..20 m at 1 m/s; the right one stops applying at 10 m."""
    rec = AsAppliedRecord(Boom.uniform(2, 3.0), FRAME, "kg/ha")
    for k, y in enumerate(np.arange(0.0, 20.01, 0.1)):
        right_on = y < 10.0 - 1e-9
        rate = 150.0 if y < 5.0 else 250.0
        rec.add(Pose(float(y), 0.0, float(y), 0.0, 1.0, float(y), k // 50, "pass"),
                [True, right_on], [rate, rate])
    return rec


def test_arrays_hold_each_sections_track() -> None:
    a = _record().arrays()
    assert a.applying.shape == (201, 2) and a.leg[-1] == 4
    assert a.centre_east_m[0].tolist() == pytest.approx([-0.75, 0.75])
    assert a.section_distance_m[-1].tolist() == pytest.approx([20.0, 20.0])
    assert a.rate[150].tolist() == [250.0, 0.0]      # not applying: no rate


def _local(feature: dict) -> shapely.Geometry:
    return shapely.transform(shape(feature["geometry"]),
                             lambda c: np.column_stack(FRAME.to_local(c[:, 0], c[:, 1])))


def test_as_applied_map_is_the_applied_ground_with_its_rates(tmp_path: Path) -> None:
    rec = _record()
    path = tmp_path / "as-applied.geojson"
    rec.save_geojson(path, cell_length_m=1.0)
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["type"] == "FeatureCollection"
    feats = data["features"]
    assert len(feats) == 20 + 10                     # 1 m cells: 20 m left, 10 m right
    union = shapely.union_all([_local(f) for f in feats])
    expected = box(-1.5, 0.0, 0.0, 20.0).union(box(0.0, 0.0, 1.5, 10.0))
    assert union.symmetric_difference(expected).area < 1e-3
    for f in feats:
        y = _local(f).centroid.y
        assert f["properties"]["rate"] == (150.0 if y < 5.0 else 250.0)
        assert f["properties"]["unit"] == "kg/ha"
        assert f["properties"]["t_end_s"] > f["properties"]["t_start_s"]


def test_cells_average_the_rate_over_their_length() -> None:
    feats = _record().to_geojson(cell_length_m=10.0)["features"]
    left = [f for f in feats if f["properties"]["section"] == 0]
    assert [f["properties"]["rate"] for f in left] == pytest.approx([200.0, 250.0])


def test_bad_samples_are_refused() -> None:
    rec = _record()
    with pytest.raises(ValueError, match="not after"):
        rec.add(Pose(1.0, 0, 0, 0, 0, 0, 0, "pass"), [True, True], [1.0, 1.0])
    with pytest.raises(ValueError, match="sections"):
        rec.add(Pose(99.0, 0, 0, 0, 0, 0, 0, "pass"), [True], [1.0])
