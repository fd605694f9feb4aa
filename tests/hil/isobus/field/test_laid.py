"""A field run's record carries its field and map: read elsewhere, it still has them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.isobus.field import load_field, load_prescription
from hil.isobus.field.laid import LaidError, field_geometry

FIELDS = Path(__file__).resolve().parents[4] / "plant_emulators" / "fertilizer" / "fields"


def _run(field: str, prescription: str) -> dict[str, object]:
    return {"field": field, "prescription": prescription,
            "field_geojson": json.loads((FIELDS / "field-rect.geojson").read_text()),
            "prescription_geojson": json.loads((FIELDS / "rates-3zones.geojson").read_text())}


def test_the_recorded_field_and_map_are_read_when_the_files_are_gone() -> None:
    fld, rx = field_geometry(_run("/nowhere/field-rect.geojson", "/nowhere/rates.geojson"))
    own = load_field(FIELDS / "field-rect.geojson")
    own_rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=own.frame)
    assert fld.boundary.equals(own.boundary) and fld.work_area.equals(own.work_area)
    assert fld.path.duration_s == own.path.duration_s
    assert rx is not None and [z.rate for z in rx.zones] == [z.rate for z in own_rx.zones]
    assert rx.rate_at_local(3.0, 30.0) == own_rx.rate_at_local(3.0, 30.0)


def test_a_record_without_them_names_the_missing_file() -> None:
    run = {"field": "/nowhere/field-rect.geojson", "prescription": ""}
    with pytest.raises(LaidError, match=r"/nowhere/field-rect\.geojson"):
        field_geometry(run)
