"""What the operator saw: masks drawn with Pillow, screens recorded as they change."""

from __future__ import annotations

import json
from pathlib import Path

from PIL import Image

from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, VtBench
from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.messages import pad, u16, u32
from hil.isobus.vt.render import (
    FONT_SIZES,
    GAP,
    colour,
    number_text,
    picture_pixels,
    render,
)
from hil.isobus.vt.screens import ScreenRecorder, vt_record, write_vt_record
from hil.isobus.vt.workingset import WorkingSet

from .pools import IDS, implement_pool

T = ObjectType


def screen(pool_ws: WorkingSet) -> Image.Image:
    return render(pool_ws, 480, 80, 60, 6)


def test_palette_and_font_sizes() -> None:
    assert colour(0) == (0, 0, 0) and colour(1) == (255, 255, 255) and colour(12) == (255, 0, 0)
    assert colour(16) == (0, 0, 0) and colour(231) == (255, 255, 255)
    assert colour(16 + 36 * 5) == (255, 0, 0)
    assert FONT_SIZES[0] == (6, 8) and FONT_SIZES[14] == (128, 192) and len(FONT_SIZES) == 15


def test_the_mask_its_fields_and_its_soft_keys_are_drawn() -> None:
    ws = WorkingSet(1, 1, None, 0.0, 0.0, pool=implement_pool())
    image = screen(ws)
    assert image.size == (480 + GAP + 80, 480)
    # the mask's background (colour 0), the rate field's box white with black digits
    assert image.getpixel((400, 400)) == (0, 0, 0)
    box = dict((c, n) for n, c in image.crop((10, 10, 160, 30)).getcolors(10_000))  # type: ignore[union-attr]
    assert box[(255, 255, 255)] > 2000 and box.get((0, 0, 0), 0) > 20
    # soft keys: silver descriptors in the column, the third slot empty
    assert image.getpixel((480 + GAP + 40, 45)) == colour(7)
    assert image.getpixel((480 + GAP + 40, 64 + 45)) == colour(7)
    assert image.getpixel((480 + GAP + 40, 2 * 64 + 5)) == (64, 64, 64)
    # the hidden box's text disappears when it is hidden
    box_area = (10, 120, 110, 140)
    shown = image.crop(box_area).getcolors(10_000)
    ws.obj(IDS.box).attrs["hidden"] = 1                        # type: ignore[union-attr]
    hidden = screen(ws).crop(box_area).getcolors(10_000)
    assert hidden == [(100 * 20, (0, 0, 0))] and shown != hidden


def test_number_text_offset_scale_decimals() -> None:
    b = PoolBuilder()
    n = b.add(T.OUTPUT_NUMBER, scale=0.01, decimals=1, offset=-100, width=80)
    obj = b.objects[-1]
    assert obj.object_id == n
    assert number_text(obj, 2600) == "25.0"
    obj.attrs.update(format=1, decimals=2)
    assert number_text(obj, 2600) == "2.50e+01"
    obj.attrs.update(format=0, options=0x08)
    assert number_text(obj, 100) == ""                          # blank zero


def test_picture_formats_and_run_length() -> None:
    b = PoolBuilder()
    b.add(T.PICTURE_GRAPHIC, width=3, actual_width=3, actual_height=2, format=0,
          raw_data=bytes([0b10100000, 0b01000000]))
    b.add(T.PICTURE_GRAPHIC, width=3, actual_width=3, actual_height=1, format=1,
          raw_data=bytes([0x12, 0x30]))
    b.add(T.PICTURE_GRAPHIC, width=4, actual_width=4, actual_height=1, format=2,
          options=0x04, raw_data=bytes([3, 12, 1, 9]))
    mono, nibbles, rle = b.objects
    assert picture_pixels(mono) == [1, 0, 1, 0, 1, 0]
    assert picture_pixels(nibbles) == [1, 2, 3]
    assert picture_pixels(rle) == [12, 12, 12, 9]


def test_screens_when_the_mask_or_a_shown_value_changes(tmp_path: Path) -> None:
    bench = VtBench([implement_pool().to_bytes()], version_label=b"SPR1")
    recorder = ScreenRecorder(bench.vt, tmp_path / "vt", min_interval_s=0.5)
    bench.run_until(3.0)
    assert len(recorder.screens) == 1 and recorder.screens[0].reason == "pool active"
    client = bench.client
    assert client is not None
    for value in range(2600, 2610):                              # 10 changes in 0.1 s
        client.change_numeric_value(IDS.rate_out, value)
    bench.run_for(1.0)
    after_values = recorder.screens[1:]
    assert 1 <= len(after_values) <= 2
    ws = bench.vt.sessions[IMPLEMENT_ADDRESS]
    assert ws.number(ws.obj(IDS.rate_out)) == 2609                # type: ignore[arg-type]
    client.change_numeric_value(IDS.rate_out, 2609)               # no visible change
    bench.run_for(1.0)
    count = len(recorder.screens)
    assert count == 1 + len(after_values)
    client.change_active_mask(IDS.ws, IDS.settings)
    bench.run_for(0.2)
    assert recorder.screens[-1].mask == IDS.settings
    assert len(recorder.screens) == count + 1
    assert all((tmp_path / "vt" / s.file).is_file() for s in recorder.screens)
    first = Image.open(tmp_path / "vt" / recorder.screens[0].file)
    assert first.size == (564, 480)
    record = vt_record(bench.vt, recorder)
    (entry,) = record["working_sets"]
    assert entry["pool_bytes"] == implement_pool().size
    assert entry["sha256"] == implement_pool().sha256
    assert entry["version_label"] == "SPR1"
    assert record["screens"][0]["file"] == "screen-0001.png"
    path = write_vt_record(tmp_path, bench.vt, recorder)
    assert json.loads(path.read_text())["working_sets"][0]["objects"] == len(implement_pool())
    # a working set that left is still in the record
    bench.implement_cf.applications.clear()
    bench.run_for(4.0)
    assert not bench.vt.sessions
    (gone,) = vt_record(bench.vt, recorder)["working_sets"]
    assert gone["sha256"] == entry["sha256"] and not gone["connected_at_end"]


def test_a_locked_mask_is_not_redrawn_until_unlocked() -> None:
    bench = VtBench([implement_pool().to_bytes()])
    recorder = ScreenRecorder(bench.vt, None, min_interval_s=0.0)
    bench.run_until(3.0)
    client = bench.client
    assert client is not None
    client.command(pad(bytes([0xBD, 1]) + u16(IDS.home) + u16(0)))
    client.command(bytes([0xA8]) + u16(IDS.rate_out) + b"\xff" + u32(1234))
    bench.run_for(0.5)
    assert len(recorder.screens) == 1
    client.command(pad(bytes([0xBD, 0]) + u16(IDS.home)))
    bench.run_for(0.5)
    assert len(recorder.screens) == 2 and recorder.screens[-1].reason.startswith("unlock")
    assert IMPLEMENT_ADDRESS in recorder.latest_png
