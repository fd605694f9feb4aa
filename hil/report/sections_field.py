"""The "Field runs under the Task Controller" section: for each field run, the prescription map
and the as-applied map side by side at one scale and one colour scale, a table per zone of the
rate prescribed and the rate laid (the depth rig: the seeding depth prescribed and the depth
sown), and the as-applied map as GeoJSON beside the report.

What was laid where comes from the run's traces and truth (:mod:`hil.report.field_maps`); the
numbers already judged are the run's ``isobus.*`` measurements in the record.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from hil.limits import is_conformance
from hil.report.field_maps import (
    FieldMapError,
    FieldRunMap,
    ZoneRate,
    field_run_map,
    is_field_run,
)
from hil.report.figures import LABEL_PT, TEXT_PT, TITLE_PT, WIDTH_IN, Image, to_image
from hil.report.markup import DASH, badge, esc, figure, fmt_num, link, note, row, table
from hil.report.record import MeasurementRow, QualRecord
from hil.report.rundata import RunData

SECTION_ID = "field-maps"


@dataclass(frozen=True)
class Words:
    """How a map's kind is named on the page."""

    done: str            # "laid", "sown"
    right_title: str
    judged: str          # the measurement the zone table shows


WORDS = {"rate": Words("laid", "as applied (truth)", "isobus.field.rate_accuracy"),
         "depth": Words("sown", "as sown (truth)", "isobus.depth.zone_error")}


def zone_headers(m: FieldRunMap) -> tuple[str, ...]:
    """The zone table's column heads for ``m``'s kind and unit."""
    w = WORDS[m.kind]
    return ("zone", f"prescribed ({m.unit})", f"{w.done} ({m.unit})",
            f"{w.done} vs prescribed", "ground " + ("applied" if m.kind == "rate" else "sown"),
            f"judged ({w.judged})")


#: the colour of a zone whose rate is 0 (nothing to apply): not on the rate scale
ZERO_COLOUR = "#e4e4e4"
COLOURMAP = "viridis"
#: the colour scale spans the map's non-zero rates widened by this share each side
SCALE_MARGIN = 0.25
#: tallest a figure gets (in): a long narrow field is drawn narrower, not taller
MAX_HEIGHT_IN = 7.5
MIN_HEIGHT_IN = 3.2
_BLURB = (
    "For each field run under the rig's Task Controller: left, the prescription map (zones "
    "filled by their rate, or their seeding depth; solid line the field boundary, dashed the "
    "work area, grey the path the tractor drove from the dot); right, the as-applied map from "
    "the truth (each row's strip, per metre of travel, in the colour of what it laid: the "
    "fertilizer rig's mass delivered at the opener over the ground it crossed, rows switched "
    "off left blank; the depth rig's true depth of the seeds its row sowed, headland turns "
    "left blank). Both maps share the scale and the colour scale. The table gives per zone "
    "what was laid or sown over all the ground the rows worked (boundaries and switches "
    "included) and, where the suite judged it, the zone's measurement away from them. The "
    "as-applied map is also written as GeoJSON (RFC 7946, WGS84) for GIS tools.")


@dataclass(frozen=True)
class RateScale:
    """One colour scale for both maps: rate → colour."""

    vmin: float
    vmax: float
    ticks: tuple[float, ...]

    @property
    def cmap(self) -> Any:
        import matplotlib

        return matplotlib.colormaps[COLOURMAP]

    @property
    def norm(self) -> Any:
        from matplotlib.colors import Normalize

        return Normalize(self.vmin, self.vmax, clip=True)

    def colour(self, rate: float) -> tuple[float, float, float, float]:
        """RGBA of a rate (a rate of 0 is :data:`ZERO_COLOUR`, off the scale)."""
        from matplotlib.colors import to_rgba

        if rate <= 0:
            return to_rgba(ZERO_COLOUR)
        return tuple(float(c) for c in self.cmap(self.norm(rate)))  # type: ignore[return-value]


def rate_scale(m: FieldRunMap) -> RateScale:
    """The scale over the map's non-zero rates (or, without any, the rates laid)."""
    rx = m.prescription
    rates = ([z.rate for z in rx.zones] + [rx.default_rate]) if rx is not None else []
    ticks = sorted({r for r in rates if r > 0})
    if not ticks:
        laid = [r for _, r in m.strips_local() if r > 0]
        if not laid:
            return RateScale(0.0, 1.0, ())
        ticks = [min(laid), max(laid)]
    lo, hi = min(ticks), max(ticks)
    return RateScale(lo * (1 - SCALE_MARGIN), hi * (1 + SCALE_MARGIN), tuple(ticks))


@dataclass
class DrawnMaps:
    """What :func:`draw_maps` drew, for checks: per zone its colour, per strip its rate and
    colour (in the order of :meth:`FieldRunMap.strips_local`)."""

    scale: RateScale
    axes: tuple[Any, Any]
    zone_colours: list[tuple[str, float, tuple[float, ...]]]
    strip_rates: list[float]
    strip_colours: list[tuple[float, ...]]


def _path_of(geom: BaseGeometry) -> Any:
    """A matplotlib path of a (multi)polygon, holes included."""
    from matplotlib.path import Path as MplPath

    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    parts = []
    for poly in polys:
        if not isinstance(poly, Polygon) or poly.is_empty:
            continue
        for ring in (poly.exterior, *poly.interiors):
            parts.append(MplPath(np.asarray(ring.coords)[:, :2], closed=True))
    return MplPath.make_compound_path(*parts) if parts else None


def _fill(ax: Any, geom: BaseGeometry, colour: Any, **kw: Any) -> tuple[float, ...] | None:
    from matplotlib.patches import PathPatch

    path = _path_of(geom)
    if path is None:
        return None
    patch = PathPatch(path, facecolor=colour, **kw)
    ax.add_patch(patch)
    return tuple(float(c) for c in patch.get_facecolor())


def _outline(ax: Any, m: FieldRunMap) -> None:
    for geom, style in ((m.field.boundary, {"ls": "-", "lw": 1.3}),
                        (m.field.work_area, {"ls": (0, (4, 2)), "lw": 1.0})):
        for poly in (geom.geoms if isinstance(geom, MultiPolygon) else [geom]):
            xy = np.asarray(poly.exterior.coords)
            ax.plot(xy[:, 0], xy[:, 1], color="#111111", zorder=4, **style)


def draw_maps(fig: Any, m: FieldRunMap) -> DrawnMaps:
    """Draw the two maps of one run on ``fig`` (its axes: map, map, colour bar)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import PathPatch

    scale = rate_scale(m)
    grid = fig.add_gridspec(1, 3, width_ratios=(1.0, 1.0, 0.07))
    left = fig.add_subplot(grid[0, 0])
    right = fig.add_subplot(grid[0, 1], sharex=left, sharey=left)
    cax = fig.add_subplot(grid[0, 2])
    zone_colours: list[tuple[str, float, tuple[float, ...]]] = []
    rx = m.prescription
    if rx is not None:
        if rx.default_rate > 0:
            outside = m.field.boundary.difference(rx.extent_local)
            _fill(left, outside, scale.colour(rx.default_rate), lw=0, zorder=1)
        for z in rx.zones:
            face = _fill(left, z.local, scale.colour(z.rate), edgecolor="white", lw=0.6,
                         zorder=2)
            if face is not None:
                zone_colours.append((z.name, z.rate, face))
    for leg_index, leg in enumerate(m.field.path.legs):
        left.plot(leg.points[:, 0], leg.points[:, 1], color="#555555", lw=0.8, zorder=3,
                  label="path" if leg_index == 0 else None)
    start = m.field.path.legs[0].points[0]
    left.plot([start[0]], [start[1]], "o", color="#555555", ms=4, zorder=3)
    strips = m.strips_local()
    rates = [rate for _, rate in strips]
    colours = [scale.colour(rate) for rate in rates]
    patches = [PathPatch(p) for p in (_path_of(g) for g, _ in strips) if p is not None]
    if len(patches) != len(strips):
        raise ValueError("an as-applied strip is not a polygon")
    if patches:
        collection = PatchCollection(patches, facecolors=colours, edgecolors=colours,
                                     linewidths=0.2, zorder=2)
        right.add_collection(collection)
        strip_colours = [tuple(float(c) for c in rgba) for rgba in collection.get_facecolor()]
    else:
        strip_colours = []
        right.text(0.5, 0.5, "nothing laid", transform=right.transAxes, ha="center",
                   va="center", fontsize=LABEL_PT, color="#444444", zorder=5,
                   bbox={"fc": "white", "ec": "#999999", "pad": 3})
    for ax, title in ((left, "prescription map"), (right, WORDS[m.kind].right_title)):
        _outline(ax, m)
        ax.set_title(title, fontsize=TITLE_PT, loc="left")
        ax.set_xlabel("east [m]", fontsize=LABEL_PT)
        ax.tick_params(labelsize=TEXT_PT)
        ax.set_aspect("equal", adjustable="box")
    left.set_ylabel("north [m]", fontsize=LABEL_PT)
    right.tick_params(labelleft=False)
    x0, y0, x1, y1 = _extent(m)
    left.set_xlim(x0, x1)
    left.set_ylim(y0, y1)
    bar = fig.colorbar(ScalarMappable(norm=scale.norm, cmap=scale.cmap), cax=cax,
                       extend="both" if scale.ticks else "neither")
    bar.set_label(m.unit, fontsize=LABEL_PT)
    if scale.ticks:
        bar.set_ticks(list(scale.ticks))
    bar.ax.tick_params(labelsize=TEXT_PT)
    return DrawnMaps(scale, (left, right), zone_colours, rates, strip_colours)


def _extent(m: FieldRunMap, margin_m: float = 1.0) -> tuple[float, float, float, float]:
    bounds = np.array([m.field.boundary.bounds,
                       *(np.r_[leg.points.min(axis=0), leg.points.max(axis=0)]
                         for leg in m.field.path.legs)])
    return (float(bounds[:, 0].min()) - margin_m, float(bounds[:, 1].min()) - margin_m,
            float(bounds[:, 2].max()) + margin_m, float(bounds[:, 3].max()) + margin_m)


def figure_height_in(m: FieldRunMap) -> float:
    """Tall enough for each map to fill its half of the width, within the page's bounds."""
    x0, y0, x1, y1 = _extent(m)
    map_width_in = (WIDTH_IN - 1.9) / 2          # less the tick labels and the colour bar
    return float(np.clip(map_width_in * (y1 - y0) / (x1 - x0) + 1.1, MIN_HEIGHT_IN,
                         MAX_HEIGHT_IN))


@contextmanager
def maps_figure(m: FieldRunMap) -> Iterator[tuple[Any, DrawnMaps]]:
    """A figure with the two maps of ``m`` drawn; closed on exit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(WIDTH_IN, figure_height_in(m)))
    try:
        yield fig, draw_maps(fig, m)
    finally:
        plt.close(fig)


def maps_image(m: FieldRunMap, alt: str) -> Image:
    with maps_figure(m) as (fig, _):
        return to_image(fig, alt)


def geojson_name(run_dir: str) -> str:
    """The as-applied GeoJSON's file name for a run's directory (``runs/test_x`` ->
    ``as-applied-runs-test_x.geojson``), in the qualification directory."""
    slug = "".join(c if c.isalnum() or c in "-_" else "-" for c in run_dir)
    return f"as-applied-{slug}.geojson"


def _zone_row(z: ZoneRate, judged: Sequence[MeasurementRow], m: FieldRunMap) -> str:
    if z.laid is None:
        diff = DASH
    elif m.kind == "depth":
        diff = f"{z.laid - z.prescribed:+.1f} {m.unit}"
    elif z.prescribed > 0:
        diff = f"{(z.laid - z.prescribed) / z.prescribed * 100:+.1f} %"
    else:
        diff = f"{fmt_num(round(z.laid, 1))} {m.unit} over none"
    marks = " ".join(f"{esc(fmt_num(ms.value))} {esc(ms.unit)} {badge(ms.status)}"
                     for ms in judged) or DASH
    laid = DASH if z.laid is None else fmt_num(round(z.laid, 1))
    return row([esc(z.name), esc(fmt_num(z.prescribed)), esc(laid), esc(diff),
                esc(f"{z.area_m2:.1f} m²"), marks])


def _zone_key(m: FieldRunMap, z: ZoneRate) -> str:
    """How the zone's measurement names the zone: the fertilizer suite by the zone's name,
    the depth suite by its depth ("40 mm")."""
    return f"{z.prescribed:g} {m.unit}" if m.kind == "depth" else z.name


def _zone_table(m: FieldRunMap, run: RunData) -> str:
    judged_name = WORDS[m.kind].judged
    accuracy: dict[str, list[MeasurementRow]] = {}
    for ms in run.measurements:
        if ms.name == judged_name:
            accuracy.setdefault(str(ms.conditions.get("zone")), []).append(ms)
    rows = [_zone_row(z, accuracy.get(_zone_key(m, z), []) if z.index >= 0 else [], m)
            for z in m.zone_rates()]
    if not rows:
        return note("the run had no prescription map: no zones to compare")
    return table(zone_headers(m), rows, "zones")


def _judged(run: RunData, m: FieldRunMap) -> str:
    in_table = WORDS[m.kind].judged
    items = "".join(
        f"<li><code>{esc(ms.name)}</code> {esc(ms.conditions_label)} = "
        + ("<i>no value</i>" if ms.value is None else
           f"<b>{esc(fmt_num(ms.value))}</b> {esc(ms.unit)}") + f" {badge(ms.status)}</li>"
        for ms in run.measurements
        if ms.name.startswith("isobus.") and not is_conformance(ms.name)
        and ms.name != in_table)
    return f'<ul class="mlist">{items}</ul>' if items else ""


def _run_block(run: RunData, qual_dir: Path) -> str:
    head = (f'<h3><a href="#{esc(run.anchor)}">{esc(run.ref.dir)}</a> · {esc(run.scenario)} '
            f"{badge(run.result) if run.result else ''}</h3>")
    if run.traces is None:
        return head + note(f"{run.ref.dir}: no traces, no maps")
    try:
        m = field_run_map(run.record, run.traces, run.truth)
        image = maps_image(m, f"prescription and as-applied maps of {run.ref.dir} "
                              f"({run.scenario})")
    except FieldMapError as exc:
        return head + note(f"{run.ref.dir}: no maps ({exc})")
    except Exception as exc:  # one run's odd data must not cost the report
        return head + note(f"{run.ref.dir}: maps failed ({type(exc).__name__}: {exc})")
    name = geojson_name(run.ref.dir)
    try:
        m.save_geojson(qual_dir / name)
        geo = (f"{link(name, 'as-applied map (GeoJSON)')}: "
               f"{len(m.geojson['features'])} row strip segments, WGS84, "
               f"property <code>rate</code> in {esc(m.unit)}")
    except OSError as exc:
        geo = esc(f"the as-applied GeoJSON could not be written: {exc}")
    rx = m.prescription
    source = (f"map <code>{esc(Path(rx.source).name)}</code>, "
              f"default {esc(fmt_num(rx.default_rate))} {esc(m.unit)}; " if rx else "")
    return (head + '<div class="grid">'
            f'<div class="plot">{figure(image)}</div>'
            f'<div>{_zone_table(m, run)}<p class="small">{source}{geo}</p>{_judged(run, m)}'
            "</div></div>")


def field_section(qual: QualRecord, runs: list[RunData]) -> str:
    """The section's HTML ("" without a field run under the TC). Writes each run's
    as-applied GeoJSON into the qualification directory, next to the report."""
    chosen = [run for run in runs if is_field_run(run.record)]
    if not chosen:
        return ""
    qual_dir = qual.path.parent
    blocks = "\n".join(_run_block(run, qual_dir) for run in chosen)
    return (f'<section id="{SECTION_ID}"><h2>Field runs under the Task Controller</h2>'
            f'<p class="small">{esc(_BLURB)}</p>{blocks}</section>')
