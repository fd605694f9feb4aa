"""Prescription maps: lookups, the default rate, and every refusal naming the file and feature."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import box, mapping

from hil.errors import ConfigError
from hil.isobus.field import LocalFrame, load_prescription, prescription_from_geojson

FRAME = LocalFrame(116.3, 40.0)


def _lonlat(geom: Any) -> dict[str, Any]:
    def unproject(c: np.ndarray) -> np.ndarray:
        return np.column_stack(FRAME.to_wgs84(c[:, 0], c[:, 1]))
    return json.loads(json.dumps(mapping(shapely.transform(geom, unproject))))


def _collection(zones: list[tuple[Any, float]], **meta: Any) -> dict[str, Any]:
    head = {"rate_property": "rate_kg_ha", "unit": "kg/ha", "default_rate": 0.0}
    head.update(meta)
    return {"type": "FeatureCollection", "prescription": head,
            "features": [{"type": "Feature", "properties": {"name": f"z{i}", "rate_kg_ha": r},
                          "geometry": _lonlat(g)} for i, (g, r) in enumerate(zones)]}


THREE = [(box(0, 0, 30, 20), 160.0), (box(0, 20, 30, 30), 240.0), (box(0, 30, 30, 50), 200.0)]


def test_rates_at_points_inside_each_zone_and_outside() -> None:
    rx = prescription_from_geojson(_collection(THREE, default_rate=50.0), frame=FRAME)
    rates = rx.rate_at_local([5, 5, 5, 5, -1], [10, 25, 40, 60, 10])
    assert rates.tolist() == [160.0, 240.0, 200.0, 50.0, 50.0]
    lon, lat = FRAME.to_wgs84(5.0, 25.0)
    assert float(rx.rate_at(lon, lat)) == 240.0
    assert rx.setpoint_ddi_value([160.0, 2.344]).tolist() == [16_000, 234]  # mg/m², DDI 6
    assert rx.unit.ddi == 6


def test_a_shared_edge_takes_the_zone_listed_first() -> None:
    rx = prescription_from_geojson(_collection(THREE), frame=FRAME)
    # the edge is within 1e-9 m of y = 20 after the round trip through degrees
    idx = rx.zone_index_local(np.array([5.0, 5.0]), np.array([20.0 - 1e-3, 20.0 + 1e-3]))
    assert idx.tolist() == [0, 1]


def test_a_map_without_a_default_rate_is_refused_and_the_caller_can_state_one() -> None:
    data = _collection(THREE)
    del data["prescription"]["default_rate"]
    with pytest.raises(ConfigError, match=r"map.geojson: \[prescription.default_rate\]"):
        prescription_from_geojson(data, source="map.geojson")
    rx = prescription_from_geojson(data, default_rate=12.5, frame=FRAME)
    assert float(rx.rate_at_local(-100.0, 0.0)) == 12.5


def test_overlapping_zones_are_refused_naming_both_features() -> None:
    data = _collection([(box(0, 0, 30, 20), 160.0), (box(0, 30, 30, 50), 200.0),
                        (box(10, 15, 20, 35), 240.0)])
    with pytest.raises(ConfigError, match=r"features\[0\].*'z0'.*overlaps zone 'z2' "
                                          r"\(features\[2\]\) by 50 m²"):
        prescription_from_geojson(data, source="m.geojson", frame=FRAME)


def _broken(mutate: Any) -> dict[str, Any]:
    data = _collection(THREE)
    mutate(data)
    return data


@pytest.mark.parametrize(("mutate", "key", "words"), [
    (lambda d: d.update(type="Feature"), "type", "FeatureCollection"),
    (lambda d: d["features"][1]["properties"].pop("rate_kg_ha"),
     r"features\[1\].properties.rate_kg_ha", "missing rate"),
    (lambda d: d["features"][2]["properties"].update(rate_kg_ha="high"),
     r"features\[2\].properties.rate_kg_ha", "finite number"),
    (lambda d: d["features"][0]["properties"].update(rate_kg_ha=-1),
     r"features\[0\].properties.rate_kg_ha", "negative"),
    (lambda d: d["features"][1].update(geometry={"type": "Point", "coordinates": [116, 40]}),
     r"features\[1\].geometry", "Polygon or MultiPolygon"),
    (lambda d: d["features"][1]["geometry"].update(
        coordinates=[[[116.3, 40.0], [116.31, 40.01], [116.31, 40.0], [116.3, 40.01],
                      [116.3, 40.0]]]), r"features\[1\].geometry", "Self-intersection"),
    (lambda d: d["features"][1]["geometry"].update(
        coordinates=[[[500000, 4400000], [500100, 4400000], [500100, 4400100],
                      [500000, 4400000]]]), r"features\[1\].geometry", "RFC 7946"),
    (lambda d: d["features"][1]["geometry"].update(coordinates=[[[116.3]]]),
     r"features\[1\].geometry", "malformed"),
    (lambda d: d["prescription"].update(unit="lb/ac"), "prescription.unit", "lb/ac"),
    (lambda d: d["prescription"].update(colour="red"), "prescription.colour", "unknown key"),
    (lambda d: d.update(crs={"type": "name", "properties": {"name": "EPSG:32650"}}), "crs",
     "EPSG:32650"),
    (lambda d: d.update(features=[]), "features", "non-empty"),
    (lambda d: d["features"].append("zone"), r"features\[3\]", "not a GeoJSON Feature"),
])
def test_malformed_maps_name_the_file_and_the_feature(mutate: Any, key: str,
                                                      words: str) -> None:
    with pytest.raises(ConfigError, match=rf"rx.geojson: \[{key}\] .*{words}"):
        prescription_from_geojson(_broken(mutate), source="rx.geojson")


def test_files_that_cannot_be_read_or_parsed(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"missing\.geojson: cannot read"):
        load_prescription(tmp_path / "missing.geojson")
    bad = tmp_path / "bad.geojson"
    bad.write_text('{"type": "FeatureCollection",\n "features": [}', encoding="utf-8")
    with pytest.raises(ConfigError, match=r"bad.geojson: not JSON: .* line 2"):
        load_prescription(bad)
    good = tmp_path / "good.geojson"
    good.write_text(json.dumps(_collection(THREE)), encoding="utf-8")
    rx = load_prescription(good, frame=FRAME)
    assert rx.source == str(good) and len(rx.zones) == 3


# a grid of random rates, and random points: the STRtree lookup against a plain scan
@settings(max_examples=60, deadline=None)
@given(rates=st.lists(st.floats(0.0, 500.0), min_size=6, max_size=6),
       points=st.lists(st.tuples(st.floats(-10.0, 40.0), st.floats(-10.0, 30.0)),
                       min_size=1, max_size=30))
def test_lookup_agrees_with_a_scan_of_the_zones(rates: list[float],
                                                points: list[tuple[float, float]]) -> None:
    cells = [box(10 * i, 10 * j, 10 * i + 10, 10 * j + 10) for j in range(2) for i in range(3)]
    rx = prescription_from_geojson(_collection(list(zip(cells, rates, strict=True)),
                                               default_rate=-0.0), frame=FRAME)
    e = np.array([p[0] for p in points])
    n = np.array([p[1] for p in points])
    got = rx.rate_at_local(e, n)
    for k, (x, y) in enumerate(points):
        hits = [i for i, z in enumerate(rx.zones) if z.local.covers(shapely.Point(x, y))]
        assert got[k] == (rates[hits[0]] if hits else 0.0)
