"""The "What the operator saw" section: the Virtual Terminal's screens on each run's time line.

For every run whose directory holds the VT's record (``vt/vt.json``, written by
:func:`hil.isobus.vt.screens.write_vt_record`), or whose record carries it (a rig's field run
with the tractor's VT: ``truth.field_run.vt``, the screens' PNGs in it,
:class:`hil.isobus.vt.fieldvt.FieldVt`): a table of the working sets that connected
(pool size, objects, version label, SHA-256, when the pool became active and whether it was
loaded from the VT's storage), then the screens in run time order as thumbnails on a time
line (each links to the full screen in the run's directory, or opens the full screen the
record carries in place: click to enlarge). The thumbnails are embedded in the page as the
report's other images are.
"""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path
from typing import Any

from PIL import Image, UnidentifiedImageError

from hil.report.markup import esc, fmt_num, note, relative_href, row, table
from hil.report.record import QualRecord
from hil.report.rundata import RunData

SECTION_ID = "vt-screens"
THUMB_WIDTH = 160
#: screens shown per run at most (the first ones; the rest are counted)
MAX_THUMBS = 60
_BLURB = (
    "The rig's Virtual Terminal as the operator saw it: the implement's active mask and its "
    "soft keys, drawn each time the mask or a value shown on it changed (value changes at "
    "most every half second), at the run time under each picture; click one to see it full "
    "size. What the VT draws and what it does not is in the documentation's Virtual "
    "Terminal page.")
HEADERS = ("address", "NAME", "pool", "objects", "version label", "SHA-256", "active at",
           "from storage")


def _vt_json(run: RunData) -> dict[str, Any] | None:
    path = run.path / "vt" / "vt.json"
    if not path.is_file():
        truth = run.record.get("truth")
        field_run = truth.get("field_run") if isinstance(truth, dict) else None
        carried = field_run.get("vt") if isinstance(field_run, dict) else None
        return carried if isinstance(carried, dict) else None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        run.notes.append(f"vt/vt.json cannot be read: {exc}")
        return None
    return data if isinstance(data, dict) else None


def _image(data: dict[str, Any], folder: Path, name: str) -> bytes | None:
    """A screen's PNG: carried in the record (base64), else the file in the run's folder."""
    carried = (data.get("screen_images") or {}).get(name)
    if isinstance(carried, str):
        try:
            return base64.b64decode(carried, validate=True)
        except ValueError:
            return None
    try:
        return (folder / name).read_bytes()
    except OSError:
        return None


def _thumb(png: bytes | None) -> str | None:
    if png is None:
        return None
    try:
        with Image.open(io.BytesIO(png)) as image:
            image.load()
            height = max(1, round(image.height * THUMB_WIDTH / image.width))
            small = image.convert("RGB").resize((THUMB_WIDTH, height),
                                                Image.Resampling.LANCZOS)
    except (OSError, UnidentifiedImageError, ValueError, ZeroDivisionError):
        return None
    buffer = io.BytesIO()
    small.save(buffer, format="PNG", optimize=True)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _sets_table(data: dict[str, Any]) -> str:
    rows = []
    for ws in data.get("working_sets", []):
        if not isinstance(ws, dict):
            continue
        pool = ws.get("pool_bytes")
        rows.append(row([
            esc(f"0x{ws.get('address', 0):02X}"), esc(str(ws.get("name") or "—")),
            esc(f"{pool:,} bytes" if isinstance(pool, int) else "no pool"),
            esc(str(ws.get("objects", "—"))), esc(str(ws.get("version_label") or "—")),
            f'<code>{esc(str(ws.get("sha256") or "—")[:16])}</code>',
            esc(f"{fmt_num(ws['activated_s'])} s" if ws.get("activated_s") is not None
                else "—"),
            esc("yes" if ws.get("loaded_from_storage") else "no")]))
    return table(HEADERS, rows, "vt-sets") if rows else note("No working set connected.")


def _timeline(run: RunData, data: dict[str, Any], qual_dir: Path) -> str:
    screens = [s for s in data.get("screens", []) if isinstance(s, dict)]
    if not screens:
        return note("No screen was drawn (no pool became active).")
    folder = run.path / str(data.get("screens_dir") or "vt")
    try:
        rel = folder.relative_to(qual_dir).as_posix()
    except ValueError:
        rel = ""
    end = max([float(s.get("time_s", 0.0)) for s in screens]
              + [float(run.ref.sim_s or 0.0)]) or 1.0
    ticks = "".join(
        f'<span title="{esc(fmt_num(s.get("time_s")))} s" style="position:absolute;'
        f'left:{100 * float(s.get("time_s", 0)) / end:.2f}%;top:0;width:2px;height:10px;'
        f'background:#36c"></span>' for s in screens)
    bar = (f'<div style="position:relative;height:10px;background:#eee;margin:4px 0 8px 0">'
           f"{ticks}</div>")
    cells = []
    carried = bool(data.get("screen_images"))
    for s in screens[:MAX_THUMBS]:
        name = str(s.get("file", ""))
        png = _image(data, folder, name)
        uri = _thumb(png)
        caption = (f"{fmt_num(s.get('time_s'))} s · mask {s.get('mask')}"
                   f" · {s.get('reason', '')}")
        if uri is None or png is None:
            cells.append(f'<div class="small">{esc(caption)} (image missing)</div>')
            continue
        img = f'<img alt="{esc("VT screen at " + caption)}" src="{uri}" width="{THUMB_WIDTH}">'
        if carried:         # no file to link to: the full screen opens in place
            full = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
            img = (f'<details><summary style="list-style:none;cursor:zoom-in">{img}</summary>'
                   f'<img alt="{esc("VT screen at " + caption + ", full size")}" '
                   f'src="{full}"></details>')
        else:
            href = relative_href(f"{rel}/{name}") if rel else None
            if href:
                img = f'<a href="{esc(href)}">{img}</a>'
        cells.append(f'<figure style="margin:0 8px 8px 0;display:inline-block;'
                     f'vertical-align:top">{img}<figcaption class="small">{esc(caption)}'
                     f"</figcaption></figure>")
    more = len(screens) - MAX_THUMBS
    where = "the run's record" if carried else (rel or "the run")
    tail = note(f"{more} later screens not shown here; all are in {where}.") \
        if more > 0 else ""
    dropped = data.get("screens_dropped") or 0
    if dropped:
        tail += note(f"{dropped} screens were not kept (the run's limit).")
    return (f'{bar}<div style="overflow-x:auto;white-space:nowrap">{"".join(cells)}</div>'
            f"{tail}")


def vt_section(qual: QualRecord, runs: list[RunData]) -> str:
    """The section's HTML ("" when no run had the VT)."""
    qual_dir = qual.path.parent
    blocks = []
    for run in runs:
        data = _vt_json(run)
        if data is None:
            continue
        title = esc(run.scenario or run.ref.dir)
        blocks.append(f'<div id="vt-{esc(run.anchor)}"><h3>{title}</h3>'
                      f'<p class="small">VT version {esc(str(data.get("vt_version", "?")))}, '
                      f'{esc(str(data.get("data_mask_px", "?")))} px data mask; '
                      f'{esc(str(data.get("commands", 0)))} commands '
                      f'({esc(str(data.get("command_errors", 0)))} answered with an error)'
                      f"</p>{_sets_table(data)}{_timeline(run, data, qual_dir)}</div>")
    if not blocks:
        return ""
    return (f'<section id="{SECTION_ID}"><h2>What the operator saw</h2>'
            f'<p class="small">{esc(_BLURB)}</p>{"".join(blocks)}</section>')
