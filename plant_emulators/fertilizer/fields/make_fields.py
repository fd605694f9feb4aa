"""Write the fertilizer rig's example field files (run from the repository root).

    python plant_emulators/fertilizer/fields/make_fields.py

``field-rect.geojson``: a 10.5 m x 50 m field with 6 m headlands, three passes of the 3 m
boom and one pass that overlaps the previous one by 1.5 m (two of the four rows over covered
ground), headland turns at 0.8 m/s, work at 6 km/h (the rig's field speed). The boom is the
rig's rows: ``[meter] rows`` of rig.toml (4) over the 3 m working width of its field scenarios.
``rates-3zones.geojson``: three rate zones across the passes (160, 240, 200 kg/ha), the middle
one a slanted band so each row crosses its boundaries at a different place.
``field-slowdown.geojson``: one straight pass of the 3 m boom through a 3 m x 50 m field that
slows from 8 km/h to 3 km/h in the middle of its work area (the ``isobus`` suite's speed-loss run:
the tractor ECU falls silent as the tractor slows, so a controller that holds its last speed
over-applies by 8/3); ``rates-uniform.geojson``: 200 kg/ha over all of it.
tests/hil/isobus/field/test_example_fields.py checks that the files are what this writes.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon, box, mapping

from hil.isobus.field import Field, FieldPath, Leg, LocalFrame, field_to_geojson, rectangular_field
from plant_emulators.fertilizer.config import load_rig_config

HERE = Path(__file__).resolve().parent
ORIGIN = LocalFrame(116.3, 40.0)  # the field's south-west corner: an arbitrary point
WIDTH_M = 3.0                     # working width D of the rig's field scenarios (width_m)
WORK_SPEED_M_S = 1.6667           # 6 km/h, the rig's field speed
TURN_SPEED_M_S = 0.8
ZONES = (("low", 160.0, [(0, 0), (1, 0), (1, 17 / 50), (0, 21 / 50)]),
         ("high", 240.0, [(0, 21 / 50), (1, 17 / 50), (1, 29 / 50), (0, 33 / 50)]),
         ("mid", 200.0, [(0, 33 / 50), (1, 29 / 50), (1, 1), (0, 1)]))

UNIFORM = (("all", 200.0, [(0, 0), (1, 0), (1, 1), (0, 1)]),)


def example_field() -> Any:
    """The example field, its rows as passes of the rig's working width."""
    rows = load_rig_config().meter.rows
    assert rows == 4, "the example field is drawn for the rig's four rows"
    return rectangular_field(ORIGIN, boom_width_m=WIDTH_M, passes=3, length_m=50.0,
                             headland_m=6.0, overlap_m=WIDTH_M / 2.0,
                             work_speed_m_s=WORK_SPEED_M_S, turn_speed_m_s=TURN_SPEED_M_S)


def slowdown_field() -> Field:
    """One pass north at 8 km/h that slows to 3 km/h over 4 m at 25 m, then stops at 47 m."""
    fast, slow, x = 8.0 / 3.6, 3.0 / 3.6, WIDTH_M / 2.0
    legs = [Leg("pass", np.array([[x, 1.0], [x, 6.0]]), 0.0, fast),
            Leg("pass", np.array([[x, 6.0], [x, 25.0]]), fast, fast),
            Leg("pass", np.array([[x, 25.0], [x, 29.0]]), fast, slow),
            Leg("pass", np.array([[x, 29.0], [x, 46.0]]), slow, slow),
            Leg("pass", np.array([[x, 46.0], [x, 47.0]]), slow, 0.0)]
    return Field(ORIGIN, box(0.0, 0.0, WIDTH_M, 50.0), box(0.0, 3.0, WIDTH_M, 47.0),
                 FieldPath(legs))


def rate_map(fld: Any, zones: Any = ZONES) -> dict[str, Any]:
    """The prescription of ``zones`` (name, rate, corners as fractions of the bounds) over the
    field's boundary."""
    x0, y0, x1, y1 = fld.boundary.bounds
    features = []
    for name, rate, corners in zones:
        local = Polygon([(x0 + u * (x1 - x0), y0 + v * (y1 - y0)) for u, v in corners])

        def unproject(c: np.ndarray) -> np.ndarray:
            lon, lat = ORIGIN.to_wgs84(c[:, 0], c[:, 1])
            return np.column_stack([np.round(lon, 9), np.round(lat, 9)])
        features.append({"type": "Feature", "properties": {"name": name, "rate_kg_ha": rate},
                         "geometry": mapping(shapely.transform(local, unproject))})
    data = {"type": "FeatureCollection",
            "prescription": {"rate_property": "rate_kg_ha", "unit": "kg/ha",
                             "default_rate": 0.0},
            "features": features}
    return json.loads(json.dumps(data))


def _text(data: dict[str, Any]) -> str:
    """GeoJSON with one feature per line (readable, and diffs stay small)."""
    head = {k: v for k, v in data.items() if k != "features"}
    lines = [json.dumps(f) for f in data["features"]]
    return (json.dumps(head)[:-1] + ', "features": [\n' + ",\n".join(lines) + "\n]}\n")


def files() -> dict[str, str]:
    """File name -> text of every example file."""
    fld = example_field()
    return {"field-rect.geojson": _text(field_to_geojson(fld)),
            "rates-3zones.geojson": _text(rate_map(fld)),
            "field-slowdown.geojson": _text(field_to_geojson(slowdown_field())),
            "rates-uniform.geojson": _text(rate_map(slowdown_field(), UNIFORM))}


def main() -> int:
    for name, text in files().items():
        (HERE / name).write_text(text, encoding="utf-8")
        print(f"wrote {HERE / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
