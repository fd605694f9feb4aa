"""The report's "Field runs under the Task Controller" section (issue 27): the prescription and
as-applied maps side by side, per zone the rate prescribed and laid, the as-applied GeoJSON.

A small synthetic field run stands in for the rig's (a real one takes ~25 s): a 3 m boom of
four rows, 1 m behind the antenna, drives one pass and an overlap pass over a two-zone map
(160 kg/ha south, 240 north); each row lays the rate under its opener inside the work area,
and row 4 is switched off for the overlap pass. Its traces and truth have the rig's names."""

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

from hil.isobus.field import Boom, LocalFrame, load_field, rectangular_field
from hil.isobus.field.path import field_to_geojson
from hil.record.traces import write_npz
from hil.report import write_html
from hil.report.field_maps import field_run_map
from hil.report.figures import DPI, to_image
from hil.report.record import load_qualification
from hil.report.rundata import load_runs
from hil.report.sections_field import field_section, geojson_name, maps_figure, rate_scale

from .conftest import Page, synthetic_record

ROWS, WIDTH_M, OFFSET_M = 4, 3.0, -1.0
LOW, HIGH = 160.0, 240.0
DRIVE_AFTER_S = 1.0
FIELD_RUN_DIR = "runs/test_field_map"


def _write_field(root: Path) -> tuple[Path, Path]:
    """A field file and a two-zone map (south half LOW, north half HIGH) in WGS84."""
    made = rectangular_field(LocalFrame(116.3, 40.0), boom_width_m=WIDTH_M, passes=1,
                             length_m=30.0, headland_m=5.0, overlap_m=1.5,
                             work_speed_m_s=2.0, turn_speed_m_s=1.0)
    field_file = root / "field.geojson"
    field_file.write_text(json.dumps(field_to_geojson(made)))
    fld = load_field(field_file)       # the frame the report will use: the boundary's own
    x0, y0, x1, y1 = fld.boundary.bounds
    mid = (y0 + y1) / 2.0

    def lonlat(geom: Any) -> Any:
        def unproject(c: np.ndarray) -> np.ndarray:
            return np.column_stack(fld.frame.to_wgs84(c[:, 0], c[:, 1]))
        return mapping(shapely.transform(geom, unproject))

    rx = {"type": "FeatureCollection",
          "prescription": {"rate_property": "rate_kg_ha", "unit": "kg/ha", "default_rate": 0},
          "features": [
              {"type": "Feature", "properties": {"name": "south", "rate_kg_ha": LOW},
               "geometry": lonlat(box(x0, y0, x1, mid))},
              {"type": "Feature", "properties": {"name": "north", "rate_kg_ha": HIGH},
               "geometry": lonlat(box(x0, mid, x1, y1))}]}
    rx_file = root / "rx.geojson"
    rx_file.write_text(json.dumps(rx))
    return field_file, rx_file


def _write_run(run_dir: Path, field_file: Path, rx_file: Path, *, lay: bool) -> None:
    """traces.npz and record.json of a field run that lays the map's rate (or nothing)."""
    fld = load_field(field_file)
    from hil.isobus.field import load_prescription
    rx = load_prescription(rx_file, frame=fld.frame)
    t = np.round(np.arange(0.0, DRIVE_AFTER_S + fld.path.duration_s + 1.0, 0.01), 6)
    pose = fld.path.sample(np.clip(t - DRIVE_AFTER_S, 0.0, None))
    boom = Boom.uniform(ROWS, WIDTH_M, fore_aft_m=OFFSET_M)
    _, centre, _ = boom.section_lines(pose.east_m, pose.north_m, pose.heading_deg)
    travel = np.vstack([np.zeros((1, ROWS)),
                        np.linalg.norm(np.diff(centre, axis=0), axis=-1)])
    rate = rx.rate_at_local(centre[..., 0], centre[..., 1])
    on = shapely.contains_xy(fld.work_area, centre[..., 0], centre[..., 1])
    overlap = np.array([fld.path.legs[int(leg)].kind == "overlap" for leg in pose.leg])
    on[:, ROWS - 1] &= ~overlap                      # section control: row 4 off, re-covered
    grams = rate / 10.0 * (WIDTH_M / ROWS) * travel * on * (1.0 if lay else 0.0)
    delivered = np.cumsum(grams, axis=0)
    arrays: dict[str, Any] = {"time_s": t, "east_m": pose.east_m, "north_m": pose.north_m,
                              "heading_deg": pose.heading_deg}
    for r in range(ROWS):
        arrays[f"delivered_{r + 1}_g"] = delivered[:, r]
    units = {"east_m": "m", "north_m": "m", "heading_deg": "deg",
             **{f"delivered_{r + 1}_g": "g" for r in range(ROWS)}}
    run_dir.mkdir(parents=True)
    write_npz(run_dir / "traces.npz", {"__units__": np.array(json.dumps(units)), **arrays})
    (run_dir / "record.json").write_text(json.dumps({
        "verdict": "no-measurements", "rig": "fertilizer", "scenario": "isobus-field-mini",
        "truth": {"field_run": {
            "boom": {"width_m": WIDTH_M, "rows": ROWS, "opener_offset_m": OFFSET_M},
            "field": str(field_file), "prescription": str(rx_file),
            "drive_after_s": DRIVE_AFTER_S, "wheel_slip": 0.0, "tc_events": []}}}))


@pytest.fixture(scope="module")
def field_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("field-map-runs")
    field_file, rx_file = _write_field(root)
    out = {}
    for key, lay in (("laid", True), ("empty", False)):
        _write_run(root / key, field_file, rx_file, lay=lay)
        out[key] = root / key
    return out


def _load(run_dir: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    from hil.record.traces import load_traces

    traces, _ = load_traces(run_dir / "traces.npz")
    return json.loads((run_dir / "record.json").read_text()), traces


def _qual_with(make_qual_dir: Callable[..., Path], run_dir: Path,
               accuracy: float | None = None) -> Path:
    record = synthetic_record()
    record["runs"].append({"dir": FIELD_RUN_DIR, "scenario": "isobus-field-mini",
                           "verdict": "no-measurements", "sim_s": 20.0, "wall_s": 0.1})
    if accuracy is not None:
        record["measurements"].append({
            "name": "isobus.field.rate_accuracy", "value": accuracy, "unit": "%", "low": 97.5,
            "high": None, "conditions": {"zone": "north", "rate_kg_ha": HIGH},
            "outcome": "pass", "marginal": False, "note": "", "run": FIELD_RUN_DIR,
            "test": "test_suites/fertilizer/test_isobus.py::test_rate_per_zone"})
    qual_dir = make_qual_dir(record)
    shutil.copytree(run_dir, qual_dir / FIELD_RUN_DIR)
    return qual_dir


def _section_only(qual_dir: Path) -> str:
    """The section as the page would hold it, without the rest of the page (faster)."""
    qual = load_qualification(qual_dir)
    return field_section(qual, load_runs(qual))


def _section(html: str) -> str:
    start = html.find('<section id="field-maps">')
    return html[start:html.index("</section>", start)] if start >= 0 else ""


def test_no_section_for_terminal_runs(qual_page: tuple[Path, str]) -> None:
    qual_dir, html = qual_page       # a step run and a terminal field run (FertSetpoint)
    assert "field-maps" not in Page(html).ids
    assert not list(qual_dir.glob("as-applied-*.geojson"))


def test_section_for_a_field_run(make_qual_dir: Callable[..., Path],
                                 field_runs: dict[str, Path]) -> None:
    qual_dir = _qual_with(make_qual_dir, field_runs["laid"], accuracy=99.2)
    html = write_html(qual_dir).read_text(encoding="utf-8")
    page = Page(html)
    assert not page.problems
    assert "field-maps" in page.ids and 'href="#field-maps"' in html
    section = _section(html)
    assert section.count("<img ") == 1 and "nothing laid" not in section
    name = geojson_name(FIELD_RUN_DIR)
    assert f'href="{name}"' in section and (qual_dir / name).is_file()
    zones = {cells[0]: cells for _, cells in page.tables["zones"][1:]}     # [0]: the head
    assert set(zones) == {"south", "north"}
    assert float(zones["south"][1]) == LOW and float(zones["north"][1]) == HIGH
    # laid over the ground applied: the map's rate, less the zone-boundary strip's mix
    assert abs(float(zones["south"][2]) - LOW) / LOW < 0.02
    assert abs(float(zones["north"][2]) - HIGH) / HIGH < 0.02
    assert "99.2 %" in zones["north"][5] and zones["south"][5] == "—"


def _pixel(png: Any, fig: Any, ax: Any, x: float, y: float) -> np.ndarray:
    px, py = ax.transData.transform((x, y)) * DPI / fig.dpi
    return np.asarray(png.getpixel((round(px), png.height - round(py))))[:3]


def _nearest(rgb: np.ndarray, scale: Any, rates: tuple[float, ...]) -> float:
    return min(rates, key=lambda r: float(np.abs(
        np.asarray(scale.colour(r)[:3]) * 255 - rgb).sum()))


def test_colours_follow_the_rates(field_runs: dict[str, Path]) -> None:
    from PIL import Image as PilImage

    m = field_run_map(*_load(field_runs["laid"]))
    scale = rate_scale(m)
    assert scale.colour(HIGH) != scale.colour(LOW)
    with maps_figure(m) as (fig, drawn):
        by_zone = {name: (rate, colour) for name, rate, colour in drawn.zone_colours}
        assert by_zone["north"] == (HIGH, scale.colour(HIGH))
        assert by_zone["south"] == (LOW, scale.colour(LOW))
        assert drawn.strip_colours == [scale.colour(r) for r in drawn.strip_rates]
        image = to_image(fig, "maps")
        with PilImage.open(io.BytesIO(base64.b64decode(image.uri.split(",", 1)[1]))) as png:
            png = png.convert("RGB")
            left, right = drawn.axes
            # on the page: between the two passes' lines in each zone, and a laid strip of
            # row 1 (first pass, x - 1.125 m) well inside each zone
            _, y0, _, y1 = m.field.work_area.bounds
            first = m.field.path.legs[0].points[0][0]
            for y, rate in ((y0 + 0.2 * (y1 - y0), LOW), (y1 - 0.2 * (y1 - y0), HIGH)):
                assert _nearest(_pixel(png, fig, left, first + 0.75, y), scale,
                                (LOW, HIGH)) == rate
                assert _nearest(_pixel(png, fig, right, first - 1.125, y), scale,
                                (LOW, HIGH)) == rate


def test_geojson_is_valid_and_its_rates_match_the_truth(field_runs: dict[str, Path]) -> None:
    record, traces = _load(field_runs["laid"])
    m = field_run_map(record, traces)
    data = json.loads(json.dumps(m.geojson))            # what the file holds
    assert data["type"] == "FeatureCollection" and "crs" not in data
    features = data["features"]
    assert features
    frame = m.field.frame
    laid = dict.fromkeys(range(1, ROWS + 1), 0.0)
    wx0, wy0, wx1, wy1 = m.field.work_area.bounds
    inner = box(wx0 - 1.0, wy0 + 0.5, wx1 + 1.0, wy1 - 0.5)      # the passes, less their ends
    checked = 0
    for f in features:
        assert f["type"] == "Feature" and f["geometry"]["type"] == "Polygon"
        ring = np.asarray(f["geometry"]["coordinates"][0])
        assert (ring[0] == ring[-1]).all() and len(ring) >= 4
        assert (np.abs(ring[:, 0] - 116.3) < 0.01).all() and (np.abs(ring[:, 1] - 40.0)
                                                               < 0.01).all()
        poly = shape(f["geometry"])
        assert poly.is_valid and poly.exterior.is_ccw          # RFC 7946 right-hand rule
        props = f["properties"]
        assert props["unit"] == "kg/ha" and 1 <= props["row"] <= ROWS
        local = shapely.transform(poly, lambda c: np.column_stack(
            frame.to_local(c[:, 0], c[:, 1])))
        laid[props["row"]] += props["rate"] * local.area / 10.0      # kg/ha x m² -> g
        # a strip inside one zone, clear of where the rows switch (the work area's edges: a
        # row on for part of a 0.1 s sample lays part of its rate there), carries the rate
        # the truth laid: the zone's
        for zone in m.prescription.zones:
            if zone.local.intersection(inner).contains(local):
                checked += 1
                assert abs(props["rate"] - zone.rate) / zone.rate < 0.01, props
    assert checked > 0.7 * len(features)
    # the map's rates over its areas add up to the mass each row delivered
    for r in range(1, ROWS + 1):
        delivered = float(traces[f"delivered_{r}_g"][-1])
        assert delivered > 0
        assert abs(laid[r] - delivered) / delivered < 0.01, r
    # row 4 was off for the overlap pass: its strips stop where the first pass's do
    first_pass_end = max(f["properties"]["t_end_s"] for f in features
                         if f["properties"]["row"] == 1
                         and f["properties"]["t_end_s"] < 0.6 * float(traces["time_s"][-1]))
    assert not [f for f in features if f["properties"]["row"] == ROWS
                and f["properties"]["t_start_s"] > first_pass_end]
    assert [f for f in features if f["properties"]["row"] == 1
            and f["properties"]["t_start_s"] > first_pass_end]


def test_a_run_that_laid_nothing_draws_an_empty_map(make_qual_dir: Callable[..., Path],
                                                    field_runs: dict[str, Path]) -> None:
    m = field_run_map(*_load(field_runs["empty"]))
    assert m.geojson == {"type": "FeatureCollection", "features": []}
    assert all(z.laid is None for z in m.zone_rates())
    with maps_figure(m) as (_, drawn):
        assert drawn.strip_rates == [] and len(drawn.zone_colours) == 2
    qual_dir = _qual_with(make_qual_dir, field_runs["empty"])
    section = _section_only(qual_dir)
    assert section.count("<img ") == 1 and 'class="note"' not in section
    name = geojson_name(FIELD_RUN_DIR)
    assert json.loads((qual_dir / name).read_text())["features"] == []
    zones = {cells[0]: cells for _, cells in Page(section).tables["zones"][1:]}
    assert zones["north"][2] == "—" and zones["south"][2] == "—"


def test_a_field_run_whose_map_is_gone_gets_a_note(make_qual_dir: Callable[..., Path],
                                                   field_runs: dict[str, Path],
                                                   tmp_path: Path) -> None:
    run_dir = tmp_path / "moved"
    shutil.copytree(field_runs["laid"], run_dir)
    record = json.loads((run_dir / "record.json").read_text())
    record["truth"]["field_run"]["prescription"] = str(tmp_path / "gone.geojson")
    (run_dir / "record.json").write_text(json.dumps(record))
    section = _section_only(_qual_with(make_qual_dir, run_dir))
    assert "<img " not in section and "gone.geojson" in section and 'class="note"' in section
