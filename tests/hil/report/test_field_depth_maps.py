"""The report's field maps for the depth rig (issue 42): the seeding-depth prescription and the
as-sown depth side by side, per zone the depth prescribed and the true depth sown.

A small synthetic depth field run stands in for the rig's (a real one takes minutes): a 2.4 m
seed line of 4 rows drives one pass and an overlap pass over a two-zone map (30 mm south, 40 mm
north); each row sows the zone's depth under its seed tube plus its own offset (row r:
``ROW_OFFSET_MM * r``), so the map's colours and the zone table have a known answer. Its
traces, truth cells and record have the depth rig's names. The drawing and page checks take a
few seconds (a figure, the report's runs): ``slow``; the default run keeps the map's numbers."""

from __future__ import annotations

import base64
import io
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely
from shapely.geometry import box, mapping, shape

from hil.isobus.field import Boom, LocalFrame, load_field, load_prescription, rectangular_field
from hil.isobus.field.path import field_to_geojson
from hil.record.traces import write_npz
from hil.report import write_html
from hil.report.field_maps import field_run_map
from hil.report.figures import DPI, to_image
from hil.report.record import load_qualification
from hil.report.rundata import load_runs
from hil.report.sections_field import field_section, maps_figure, rate_scale

from .conftest import Page, synthetic_record

ROWS, WIDTH_M = 4, 2.4
SHALLOW, DEEP = 30.0, 40.0
ROW_OFFSET_MM = 0.5
DRIVE_AFTER_S = 1.0
RUN_DIR = "runs/test_depth_follows_the_map"


def _write_field(root: Path) -> tuple[Path, Path]:
    made = rectangular_field(LocalFrame(116.3, 40.0), boom_width_m=WIDTH_M, passes=1,
                             length_m=30.0, headland_m=5.0, overlap_m=1.2,
                             work_speed_m_s=2.0, turn_speed_m_s=1.0)
    field_file = root / "field.geojson"
    field_file.write_text(json.dumps(field_to_geojson(made)))
    fld = load_field(field_file)
    x0, y0, x1, y1 = fld.boundary.bounds
    mid = (y0 + y1) / 2.0

    def lonlat(geom: Any) -> Any:
        def unproject(c: np.ndarray) -> np.ndarray:
            return np.column_stack(fld.frame.to_wgs84(c[:, 0], c[:, 1]))
        return mapping(shapely.transform(geom, unproject))

    rx = {"type": "FeatureCollection",
          "prescription": {"rate_property": "depth_mm", "unit": "mm", "default_rate": 35.0},
          "features": [
              {"type": "Feature", "properties": {"name": "moist", "depth_mm": SHALLOW},
               "geometry": lonlat(box(x0, y0, x1, mid))},
              {"type": "Feature", "properties": {"name": "dry", "depth_mm": DEEP},
               "geometry": lonlat(box(x0, mid, x1, y1))}]}
    rx_file = root / "depths.geojson"
    rx_file.write_text(json.dumps(rx))
    return field_file, rx_file


def _write_run(run_dir: Path, field_file: Path, rx_file: Path) -> None:
    """traces.npz, truth.npz and record.json of a depth field run that sows the map's depth
    (plus each row's offset) wherever it drives."""
    fld = load_field(field_file)
    rx = load_prescription(rx_file, frame=fld.frame)
    t = np.round(np.arange(0.0, DRIVE_AFTER_S + fld.path.duration_s + 1.0, 0.01), 6)
    pose = fld.path.sample(np.clip(t - DRIVE_AFTER_S, 0.0, None))
    distance = pose.distance_m
    on_pass = np.array([fld.path.legs[int(k)].kind == "pass" for k in pose.leg], dtype=float)
    traces = {"time_s": t, "distance_m": distance, "seed_east_m": pose.east_m,
              "seed_north_m": pose.north_m, "heading_deg": pose.heading_deg,
              "on_pass": on_pass}
    units = {"distance_m": "m", "seed_east_m": "m", "seed_north_m": "m",
             "heading_deg": "deg", "on_pass": "1"}
    # truth cells: one per 10 mm of travel, each row's seed tube at the map's depth
    cells_d = np.arange(0.005, float(distance[-1]), 0.01)
    at = np.clip(np.searchsorted(distance, cells_d), 0, t.size - 1)
    boom = Boom.uniform(ROWS, WIDTH_M, fore_aft_m=0.0)
    _, centre, _ = boom.section_lines(pose.east_m[at], pose.north_m[at], pose.heading_deg[at])
    depth = (rx.rate_at_local(centre[..., 0], centre[..., 1])
             + ROW_OFFSET_MM * np.arange(ROWS)[None, :])
    run_dir.mkdir(parents=True)
    write_npz(run_dir / "traces.npz", {"__units__": np.array(json.dumps(units)), **traces})
    np.savez(run_dir / "truth.npz", distance_m=cells_d, depth_mm=depth)
    (run_dir / "record.json").write_text(json.dumps({
        "verdict": "no-measurements", "rig": "sowing_depth", "scenario": "isobus-depth-mini",
        "truth": {"field_run": {
            "seed_line": {"width_m": WIDTH_M, "offset_m": -1.9},
            "field": str(field_file), "prescription": str(rx_file),
            "drive_after_s": DRIVE_AFTER_S, "wheel_slip": 0.0, "tc_events": []}}}))


@pytest.fixture(scope="module")
def depth_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("depth-map-run")
    field_file, rx_file = _write_field(root)
    _write_run(root / "run", field_file, rx_file)
    return root / "run"


def _load(run_dir: Path) -> tuple[dict[str, Any], dict[str, np.ndarray], dict[str, Any]]:
    from hil.record.traces import load_traces

    traces, _ = load_traces(run_dir / "traces.npz")
    with np.load(run_dir / "truth.npz") as data:
        truth = {k: data[k] for k in data.files}
    return json.loads((run_dir / "record.json").read_text()), traces, truth


def _pixel(png: Any, fig: Any, ax: Any, x: float, y: float) -> np.ndarray:
    px, py = ax.transData.transform((x, y)) * DPI / fig.dpi
    return np.asarray(png.getpixel((round(px), png.height - round(py))))[:3]


def test_the_sown_depth_is_the_truth_per_zone_and_row(depth_run: Path) -> None:
    m = field_run_map(*_load(depth_run))
    assert m.kind == "depth" and m.unit == "mm"
    zones = {z.name: z for z in m.zone_rates()}
    assert zones["moist"].prescribed == SHALLOW and zones["dry"].prescribed == DEEP
    # every row's offset, averaged over the rows: 0.75 mm; the boundary's mixed strips move
    # the mean by less than the zone's share of them
    mean_offset = ROW_OFFSET_MM * (ROWS - 1) / 2.0
    assert abs(zones["moist"].laid - (SHALLOW + mean_offset)) < 0.3
    assert abs(zones["dry"].laid - (DEEP + mean_offset)) < 0.3
    # the turns are not sown ground: no strip there
    data = m.geojson
    assert data["features"] and {f["properties"]["unit"] for f in data["features"]} == {"mm"}
    assert all(f["properties"]["depth_mm"] == f["properties"]["rate"] for f in data["features"])
    frame = m.field.frame
    wx0, wy0, wx1, wy1 = m.field.work_area.bounds
    inner = box(wx0 - 2.0, wy0 + 1.0, wx1 + 2.0, wy1 - 1.0)
    checked = 0
    for f in data["features"]:
        local = shapely.transform(shape(f["geometry"]), lambda c: np.column_stack(
            frame.to_local(c[:, 0], c[:, 1])))
        assert local.centroid.y > m.field.boundary.bounds[1] - 0.5
        for zone in m.prescription.zones:
            if zone.local.intersection(inner).contains(local):
                row = int(f["properties"]["section"])
                assert abs(f["properties"]["rate"] - (zone.rate + ROW_OFFSET_MM * row)) < 0.01
                checked += 1
    assert checked > 0.6 * len(data["features"])


@pytest.mark.slow
def test_the_maps_share_the_depth_colours(depth_run: Path) -> None:
    from PIL import Image as PilImage

    m = field_run_map(*_load(depth_run))
    scale = rate_scale(m)
    assert scale.ticks == (SHALLOW, 35.0, DEEP)
    with maps_figure(m) as (fig, drawn):
        left, right = drawn.axes
        assert right.get_title(loc="left") == "as sown (truth)"
        assert {name: rate for name, rate, _ in drawn.zone_colours} == {"moist": SHALLOW,
                                                                        "dry": DEEP}
        image = to_image(fig, "maps")
        with PilImage.open(io.BytesIO(base64.b64decode(image.uri.split(",", 1)[1]))) as png:
            png = png.convert("RGB")
            _, y0, _, y1 = m.field.work_area.bounds
            first = m.field.path.legs[0].points[0][0]
            for y, depth in ((y0 + 0.2 * (y1 - y0), SHALLOW), (y1 - 0.2 * (y1 - y0), DEEP)):
                for ax, x in ((left, first + 0.3), (right, first - 0.9)):    # row 1's strip
                    rgb = _pixel(png, fig, ax, x, y)
                    nearest = min((SHALLOW, DEEP), key=lambda d: float(np.abs(
                        np.asarray(scale.colour(d)[:3]) * 255 - rgb).sum()))
                    assert nearest == depth, (ax.get_title(loc="left"), y)


@pytest.mark.slow
def test_the_section_names_depths_and_the_zone_error(make_qual_dir: Callable[..., Path],
                                                    depth_run: Path) -> None:
    record = synthetic_record()
    record["runs"].append({"dir": RUN_DIR, "scenario": "isobus-depth-mini",
                           "verdict": "pass", "sim_s": 30.0, "wall_s": 0.1})
    record["measurements"].append({
        "name": "isobus.depth.zone_error", "value": 1.4, "unit": "mm", "low": None,
        "high": 3.0, "conditions": {"zone": "40 mm"}, "outcome": "pass", "marginal": False,
        "note": "", "run": RUN_DIR,
        "test": "test_suites/sowing_depth/test_depth_isobus.py::test_depth_follows_the_map"})
    qual_dir = make_qual_dir(record)
    shutil.copytree(depth_run, qual_dir / RUN_DIR)
    qual = load_qualification(qual_dir)
    section = field_section(qual, load_runs(qual))
    page = Page(section)
    assert not page.problems and section.count("<img ") == 1 and 'class="note"' not in section
    head, *rows = page.tables["zones"]
    assert head[1][:4] == ["zone", "prescribed (mm)", "sown (mm)", "sown vs prescribed"]
    zones = {cells[0]: cells for _, cells in rows}
    assert zones["dry"][3].startswith("+0.") and zones["dry"][3].endswith(" mm")
    assert "1.4 mm" in zones["dry"][5] and zones["moist"][5] == "—"
    assert "property rate in mm" in " ".join(" ".join(page.text).split())
    html = write_html(qual_dir).read_text(encoding="utf-8")
    assert not Page(html).problems and 'id="field-maps"' in html
