"""The fertilizer rig's example field files: what their generator writes, and a good drive."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
import shapely

from hil.isobus.field import Boom, ImplementModel, drive_field, load_field, load_prescription
from hil.isobus.field.coverage import needed_ground
from hil.metrics.application_map import (
    after_rate_change,
    cell_accuracy,
    section_switching,
    transition_distances,
)

FIELDS = Path(__file__).resolve().parents[4] / "plant_emulators" / "fertilizer" / "fields"


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_fields", FIELDS / "make_fields.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_shipped_files_are_what_the_generator_writes() -> None:
    for name, text in _generator().files().items():
        assert (FIELDS / name).read_text(encoding="utf-8") == text, (
            f"{name} is stale: python plant_emulators/fertilizer/fields/make_fields.py")


def test_the_example_field_driven_well_meets_every_application_measurement() -> None:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    assert [(z.name, z.rate) for z in rx.zones] == [("low", 160.0), ("high", 240.0),
                                                    ("mid", 200.0)]
    boom = Boom.uniform(4, 3.0, fore_aft_m=-1.0, turn_on_s=0.5, turn_off_s=0.3)
    a = drive_field(fld, boom, rx, dt_s=0.1,
                    implement=ImplementModel(rate_delay_s=0.43)).arrays()
    pres = rx.rate_at_local(a.centre_east_m, a.centre_north_m)
    widths = [s.width_m for s in boom.sections]
    cells = rx.zone_index_local(a.centre_east_m, a.centre_north_m)
    acc = cell_accuracy(cells, a.section_distance_m, widths, a.applying, a.rate, pres,
                        exclude=after_rate_change(a.section_distance_m, pres, 2.0))
    assert len(acc.cells) == 3 and acc.worst_abs_error_pct < 1.0
    trans = transition_distances(a.section_distance_m, a.applying, a.rate, pres)
    assert len(trans.transitions) == 2 * 4 * 3 + 2 * 2 and trans.worst_m < 1.5
    need = needed_ground(boom, a.east_m, a.north_m, a.heading_deg, a.leg, a.applying,
                         fld.work_area)
    inside = shapely.contains_xy(fld.work_area, a.centre_east_m, a.centre_north_m)
    sw = section_switching(a.section_distance_m, a.applying, need, inside_work_area=inside)
    assert sw.worst_error_m <= 0.17 and sw.overlap_m + sw.skip_m < 1.0
    # the overlap pass (south-bound, the last) left its two western (right-hand) rows off
    last = a.leg >= min(i for i, leg in enumerate(fld.path.legs) if leg.kind == "overlap")
    assert np.sum(a.applying[last, 2:]) <= 2 and np.sum(a.applying[last, :2]) > 200
