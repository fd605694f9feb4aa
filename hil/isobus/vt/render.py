"""What the operator sees, drawn with Pillow: the active mask and its soft keys.

:func:`render` draws a working set's screen as the VT shows it now: the data (or alarm) mask
area, a square of the VT's size, and to its right the soft key column (the active mask's soft
key mask, one descriptor per key). What is drawn:

- data and alarm masks, containers (hidden ones not), buttons (background, border, children),
  soft keys, object pointers (what they point to);
- output and input strings (font colour, size, horizontal and vertical justification,
  transparency), output and input numbers (``(value + offset) * scale`` with the decimals, or
  exponential format), input booleans (a check box), input and output lists (the selected
  item);
- lines, rectangles (line suppression, fill with the line or fill colour), ellipses (closed,
  open, segment, section), polygons, meters (arc, ticks, needle), linear and arched bar
  graphs (value and target line);
- picture graphics (monochrome, 4- and 8-bit, run-length encoded, transparency colour,
  scaled to their width);
- colours from the standard palette (0-15 named, 16-231 the 6 x 6 x 6 cube, 232-255 a grey
  ramp as AgIsoStack++ has it).

Text is set in cells of the standard's font sizes (6 x 8 to 128 x 192 pixels), one character
per cell, drawn with DejaVu Sans Mono where the system has it and Pillow's own font
otherwise: the layout is the standard's, the glyphs are not a terminal's. Not drawn: window
masks and key groups (version 4 user layout), graphics contexts, animations, scaled graphics
and graphic data, external object pointers (their default object is drawn), auxiliary
objects, colour maps and palettes, font styles (bold, italic, underline, flashing,
proportional), line art patterns (lines are solid), fill patterns (drawn as the fill colour),
a locked mask's changes until it is unlocked, and anything off its parent's area is clipped
only at the mask's edge.
"""

from __future__ import annotations

import math
from functools import cache, lru_cache
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.commands import is_enabled
from hil.isobus.vt.errors import NO_OBJECT
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.workingset import WorkingSet, decode_text

T = ObjectType
RGB = tuple[int, int, int]

FONT_SIZES: tuple[tuple[int, int], ...] = (
    (6, 8), (8, 8), (8, 12), (12, 16), (16, 16), (16, 24), (24, 32), (32, 32), (32, 48),
    (48, 64), (64, 64), (64, 96), (96, 128), (128, 128), (128, 192))
"""Font size code -> (width, height) of a character cell, pixels (ISO 11783-6)."""

_FONT_FILES = ("/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf",
               "/usr/share/fonts/dejavu/DejaVuSansMono.ttf")
GAP = 4
"""Pixels between the mask area and the soft key column, and between soft keys."""


def _palette() -> tuple[RGB, ...]:
    named: list[RGB] = [(0, 0, 0), (255, 255, 255), (0, 153, 0), (0, 153, 153), (153, 0, 0),
                        (153, 0, 153), (153, 153, 0), (204, 204, 204), (153, 153, 153),
                        (0, 0, 255), (0, 255, 0), (0, 255, 255), (255, 0, 0), (255, 0, 255),
                        (255, 255, 0), (0, 0, 153)]
    cube = [(51 * (i // 36), 51 * (i // 6 % 6), 51 * (i % 6)) for i in range(216)]
    grey = [(round(10 + 10.6 * k),) * 3 for k in range(24)]
    return tuple(named + cube + grey)  # type: ignore[arg-type]


PALETTE: tuple[RGB, ...] = _palette()


def colour(index: int) -> RGB:
    """The RGB of a VT colour index."""
    return PALETTE[index & 0xFF]


@cache
def _font(height: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    for path in _FONT_FILES:
        if Path(path).is_file():
            return ImageFont.truetype(path, height, layout_engine=ImageFont.Layout.BASIC)
    return ImageFont.load_default(height)


@cache
def _glyph_font(cell_w: int, cell_h: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """The largest font whose 'W' fits a cell."""
    size = cell_h
    while size > 4:
        font = _font(size)
        box = font.getbbox("W")
        if box[2] - box[0] <= cell_w and size <= cell_h:
            return font
        size -= 1
    return _font(4)


class _Painter:
    def __init__(self, ws: WorkingSet, image: Image.Image, mask_px: int, key_w: int,
                 key_h: int) -> None:
        self.ws = ws
        self.image = image
        self.draw = ImageDraw.Draw(image)
        self.mask_px = mask_px
        self.key_w = key_w
        self.key_h = key_h

    # -- the tree --------------------------------------------------------------------------------

    def object(self, obj: VtObject, x: int, y: int, depth: int = 0) -> None:
        if depth > 32:
            return
        ws = self.ws
        if obj.type == T.OBJECT_POINTER:
            target = ws.obj(obj["value"])
            if target is not None:
                self.object(target, x, y, depth + 1)
            return
        if obj.type == T.EXTERNAL_OBJECT_POINTER:
            target = ws.obj(obj["default_object"])
            if target is not None:
                self.object(target, x, y, depth + 1)
            return
        if obj.type == T.CONTAINER and obj["hidden"]:
            return
        draw = _DRAW.get(obj.type)
        if draw is not None:
            draw(self, obj, x, y)
        if obj.type in (T.DATA_MASK, T.ALARM_MASK, T.CONTAINER, T.BUTTON, T.KEY):
            offset = 3 if obj.type == T.BUTTON else 0
            for child_id, cx, cy in obj.children:
                child = ws.obj(child_id)
                if child is not None:
                    self.object(child, x + cx + offset, y + cy + offset, depth + 1)

    # -- primitives ------------------------------------------------------------------------------

    def rect(self, x: int, y: int, w: int, h: int, fill: RGB | None, outline: RGB | None = None,
             width: int = 1) -> None:
        if w <= 0 or h <= 0:
            return
        self.draw.rectangle((x, y, x + w - 1, y + h - 1), fill=fill, outline=outline,
                            width=width if outline is not None else 0)

    def text(self, text: str, x: int, y: int, w: int, h: int, font_id: int,
             justification: int, wrap: bool) -> None:
        font = self.ws.obj(font_id)
        size = font["font_size"] if font is not None else 2
        fg = colour(font["font_colour"] if font is not None else 0)
        cw, chh = FONT_SIZES[min(size, 14)]
        glyphs = _glyph_font(cw, chh)
        per_line = max(1, w // cw) if w else len(text)
        lines = [text[i:i + per_line] for i in range(0, len(text), per_line)] if wrap \
            else [text]
        lines = lines[:max(1, h // chh)] if h else lines
        block = len(lines) * chh
        vertical = (justification >> 2) & 0x03
        top = y + (0 if vertical == 0 else (h - block) // 2 if vertical == 1 else h - block)
        for n, line in enumerate(lines):
            line = line[:per_line]
            width = len(line) * cw
            horizontal = justification & 0x03
            left = x + (0 if horizontal == 0 else (w - width) // 2 if horizontal == 1
                        else w - width)
            for i, ch in enumerate(line):
                if ch.isprintable() and ch != " ":
                    self.draw.text((left + i * cw + cw / 2, top + n * chh + chh / 2), ch,
                                   fill=fg, font=glyphs, anchor="mm")

    def line_attrs(self, line_id: int) -> tuple[RGB, int]:
        line = self.ws.obj(line_id)
        if line is None:
            return colour(0), 1
        return colour(line["line_colour"]), line["line_width"]

    def fill_of(self, fill_id: int, line_rgb: RGB) -> RGB | None:
        fill = self.ws.obj(fill_id)
        if fill is None or fill["fill_type"] == 0:
            return None
        if fill["fill_type"] == 1:
            return line_rgb
        return colour(fill["fill_colour"])


def _mask(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    p.rect(x, y, p.mask_px, p.mask_px, colour(obj["background_colour"]))


def _button(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    enabled = is_enabled(obj)
    p.rect(x, y, obj["width"], obj["height"], colour(obj["background_colour"]),
           colour(obj["border_colour"] if enabled else 8), 2)


def _key(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    p.rect(x, y, p.key_w, p.key_h, colour(obj["background_colour"]), colour(8), 1)


def _string(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w, h = obj["width"], obj["height"]
    options = obj["options"]
    if not options & 0x01:                                 # not transparent
        p.rect(x, y, w, h, colour(obj["background_colour"]))
    p.text(p.ws.text(obj), x, y, w, h, obj["font_attributes"], obj["justification"],
           bool(options & 0x02))
    if obj.type == T.INPUT_STRING:
        p.rect(x, y, w, h, None, colour(8) if is_enabled(obj) else colour(7))


def number_text(obj: VtObject, raw: int) -> str:
    """An output or input number's text: ``(raw + offset) * scale`` with its decimals, or in
    exponential format (format 1); options bit 2 (leading zeros) and bit 3 (blank zero)."""
    value = (raw + int(obj["offset"])) * float(obj["scale"])
    decimals = int(obj["decimals"])
    options = obj["options"]
    if options & 0x08 and value == 0:
        return ""
    if obj["format"] == 1:
        return f"{value:.{decimals}e}"
    text = f"{value:.{decimals}f}"
    if options & 0x04:
        width = max(1, obj["width"] // 8)
        text = text.zfill(width)
    return text


def _number(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w, h = obj["width"], obj["height"]
    options = obj["options"]
    if not options & 0x01:
        p.rect(x, y, w, h, colour(obj["background_colour"]))
    p.text(number_text(obj, p.ws.number(obj)), x, y, w, h, obj["font_attributes"],
           obj["justification"], False)
    if obj.type == T.INPUT_NUMBER:
        p.rect(x, y, w, h, None, colour(8) if is_enabled(obj) else colour(7))


def _boolean(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w = obj["width"]
    font = p.ws.obj(obj["foreground_colour"])
    fg = colour(font["font_colour"] if font is not None else 0)
    p.rect(x, y, w, w, colour(obj["background_colour"]), fg, 1)
    if p.ws.number(obj):
        p.draw.line((x + 2, y + w // 2, x + w // 3, y + w - 3, x + w - 3, y + 2), fill=fg,
                    width=max(1, w // 8))


def _list(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    index = p.ws.number(obj)
    items = obj["items"]
    if 0 <= index < len(items) and items[index] != NO_OBJECT:
        item = p.ws.obj(items[index])
        if item is not None:
            p.object(item, x, y, 1)
    if obj.type == T.INPUT_LIST:
        p.rect(x, y, obj["width"], obj["height"], None, colour(8))


def _line(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    rgb, width = p.line_attrs(obj["line_attributes"])
    w, h = obj["width"] - 1, obj["height"] - 1
    if width == 0:
        return
    points = (x, y, x + w, y + h) if obj["line_direction"] == 0 else (x, y + h, x + w, y)
    p.draw.line(points, fill=rgb, width=width)


def _rectangle(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    rgb, width = p.line_attrs(obj["line_attributes"])
    w, h = obj["width"], obj["height"]
    fill = p.fill_of(obj["fill_attributes"], rgb)
    if fill is not None:
        p.rect(x, y, w, h, fill)
    if width == 0:
        return
    suppress = obj["line_suppression"]
    edges = ((0x01, (x, y, x + w - 1, y)), (0x02, (x + w - 1, y, x + w - 1, y + h - 1)),
             (0x04, (x, y + h - 1, x + w - 1, y + h - 1)), (0x08, (x, y, x, y + h - 1)))
    for bit, points in edges:
        if not suppress & bit:
            p.draw.line(points, fill=rgb, width=width)


def _ellipse(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    rgb, width = p.line_attrs(obj["line_attributes"])
    box = (x, y, x + obj["width"] - 1, y + obj["height"] - 1)
    fill = p.fill_of(obj["fill_attributes"], rgb)
    kind = obj["ellipse_type"]
    # angles in units of 2 degrees, counter-clockwise from 3 o'clock; Pillow's go clockwise
    start, end = -2 * obj["end_angle"], -2 * obj["start_angle"]
    if kind == 0 or start == end:
        p.draw.ellipse(box, fill=fill, outline=rgb, width=width)
    elif kind == 1:
        p.draw.arc(box, start, end, fill=rgb, width=width)
    elif kind == 2:
        p.draw.chord(box, start, end, fill=fill, outline=rgb, width=width)
    else:
        p.draw.pieslice(box, start, end, fill=fill, outline=rgb, width=width)


def _polygon(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    rgb, width = p.line_attrs(obj["line_attributes"])
    points = [(x + px, y + py) for px, py in obj["points"]]
    if len(points) < 2:
        return
    fill = p.fill_of(obj["fill_attributes"], rgb) if obj["polygon_type"] != 3 else None
    if obj["polygon_type"] == 3:                           # open
        p.draw.line(points, fill=rgb, width=width)
    else:
        p.draw.polygon(points, fill=fill, outline=rgb, width=width)


def _fraction(p: _Painter, obj: VtObject) -> float:
    low, high = obj["min_value"], obj["max_value"]
    value = p.ws.number(obj)
    return 0.0 if high <= low else min(1.0, max(0.0, (value - low) / (high - low)))


def _meter(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w = obj["width"]
    start, end = 2 * obj["start_angle"], 2 * obj["end_angle"]
    span = (end - start) % 360 or 360
    if obj["options"] & 0x01:                              # draw arc
        p.draw.arc((x, y, x + w - 1, y + w - 1), -start - span, -start,
                   fill=colour(obj["arc_and_tick_colour"]), width=1)
    if obj["options"] & 0x02:                              # draw border
        p.draw.ellipse((x, y, x + w - 1, y + w - 1), outline=colour(obj["border_colour"]))
    f = _fraction(p, obj)
    clockwise = obj["options"] & 0x08                      # deflection clockwise
    angle = start + span - f * span if clockwise else start + f * span
    cx = cy = w / 2
    r = w / 2 - 2
    p.draw.line((x + cx, y + cy, x + cx + r * math.cos(math.radians(angle)),
                 y + cy - r * math.sin(math.radians(angle))),
                fill=colour(obj["needle_colour"]), width=2)


def _linear_bar(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w, h = obj["width"], obj["height"]
    f = _fraction(p, obj)
    rgb = colour(obj["colour"])
    options = obj["options"]
    horizontal = bool(options & 0x08)
    if options & 0x01:
        p.rect(x, y, w, h, None, rgb)
    if horizontal:
        p.rect(x, y, round(w * f), h, rgb)
    else:
        filled = round(h * f)
        p.rect(x, y + h - filled, w, filled, rgb)


def _arched_bar(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    w, h = obj["width"], obj["height"]
    start, end = 2 * obj["start_angle"], 2 * obj["end_angle"]
    span = (end - start) % 360 or 360
    f = _fraction(p, obj)
    box = (x, y, x + w - 1, y + h - 1)
    bar = max(1, obj["bar_graph_width"])
    if obj["options"] & 0x01:
        p.draw.arc(box, -start - span, -start, fill=colour(obj["colour"]), width=1)
    if f > 0:
        p.draw.arc(box, -start - span * f, -start, fill=colour(obj["colour"]), width=bar)


def picture_pixels(obj: VtObject) -> list[int]:
    """A picture graphic's colour indexes, row by row (``actual_width`` x ``actual_height``):
    run-length decoded when options bit 2 says so, rows of 1- and 4-bit pictures padded to
    whole bytes."""
    raw: bytes = obj["raw_data"]
    if obj["options"] & 0x04:
        out = bytearray()
        for i in range(0, len(raw) - 1, 2):
            out += bytes([raw[i + 1]]) * raw[i]
        raw = bytes(out)
    width, height, fmt = obj["actual_width"], obj["actual_height"], obj["format"]
    pixels: list[int] = []
    if fmt == 2:
        for row in range(height):
            pixels += raw[row * width:(row + 1) * width]
    else:
        bits = 1 if fmt == 0 else 4
        per_row = (width * bits + 7) // 8
        for row in range(height):
            line = raw[row * per_row:(row + 1) * per_row]
            for col in range(width):
                if bits == 1:
                    byte = line[col // 8] if col // 8 < len(line) else 0
                    pixels.append((byte >> (7 - col % 8)) & 1)
                else:
                    byte = line[col // 2] if col // 2 < len(line) else 0
                    pixels.append(byte >> 4 if col % 2 == 0 else byte & 0x0F)
    pixels += [0] * (width * height - len(pixels))
    return pixels[:width * height]


_FLAT_PALETTE = [c for rgb in PALETTE for c in rgb]


@lru_cache(maxsize=256)
def _picture_image(raw: bytes, width: int, height: int, fmt: int, options: int,
                   key: int, shown_w: int) -> Image.Image:
    obj = VtObject(NO_OBJECT, T.PICTURE_GRAPHIC, {
        "raw_data": raw, "actual_width": width, "actual_height": height, "format": fmt,
        "options": options})
    indexes = bytes(picture_pixels(obj))
    image = Image.frombytes("P", (width, height), indexes)
    image.putpalette(_FLAT_PALETTE)
    rgba = image.convert("RGBA")
    if options & 0x01:                                     # transparent colour
        table = bytes(0 if i == key else 255 for i in range(256))
        rgba.putalpha(Image.frombytes("L", (width, height), indexes.translate(table)))
    shown_h = max(1, round(height * shown_w / width))
    if (shown_w, shown_h) != (width, height):
        rgba = rgba.resize((shown_w, shown_h), Image.Resampling.NEAREST)
    return rgba


def _picture(p: _Painter, obj: VtObject, x: int, y: int) -> None:
    width, height = obj["actual_width"], obj["actual_height"]
    if not width or not height:
        return
    key = obj["transparency_colour"]
    if obj["format"] == 0:                                 # monochrome: 0 black, 1 white
        key = 1 if key else 0
    image = _picture_image(obj["raw_data"], width, height, obj["format"], obj["options"], key,
                           obj["width"] or width)
    p.image.paste(image, (x, y), image)


_DRAW = {
    T.DATA_MASK: _mask, T.ALARM_MASK: _mask, T.BUTTON: _button, T.KEY: _key,
    T.OUTPUT_STRING: _string, T.INPUT_STRING: _string, T.OUTPUT_NUMBER: _number,
    T.INPUT_NUMBER: _number, T.INPUT_BOOLEAN: _boolean, T.INPUT_LIST: _list,
    T.OUTPUT_LIST: _list, T.OUTPUT_LINE: _line, T.OUTPUT_RECTANGLE: _rectangle,
    T.OUTPUT_ELLIPSE: _ellipse, T.OUTPUT_POLYGON: _polygon, T.OUTPUT_METER: _meter,
    T.OUTPUT_LINEAR_BAR_GRAPH: _linear_bar, T.OUTPUT_ARCHED_BAR_GRAPH: _arched_bar,
    T.PICTURE_GRAPHIC: _picture,
}


def render(ws: WorkingSet, mask_px: int = 480, key_w: int = 80, key_h: int = 60,
           keys: int = 6) -> Image.Image:
    """The working set's screen now: its active mask and its soft key column (RGB)."""
    height = max(mask_px, keys * (key_h + GAP) - GAP)
    image = Image.new("RGB", (mask_px + GAP + key_w, height), (64, 64, 64))
    painter = _Painter(ws, image, mask_px, key_w, key_h)
    mask = ws.obj(ws.active_mask)
    if mask is not None:
        painter.object(mask, 0, 0)
    # anything drawn past the mask area is the mask's overflow: cut at its edge
    painter.rect(mask_px, 0, GAP + key_w, height, (64, 64, 64))
    skm = ws.resolve(ws.soft_key_mask)
    if skm is not None:
        for i, key_id in enumerate(skm["keys"][:keys]):
            key = ws.resolve(key_id)
            if key is not None:
                painter.object(key, mask_px + GAP, i * (key_h + GAP))
    return image


def visible_signature(ws: WorkingSet) -> tuple[object, ...]:
    """What decides the picture: the masks and every shown object's state (a cheap test of
    whether anything visible changed since the last drawing)."""
    out: list[object] = [ws.active_mask, ws.soft_key_mask]
    for obj, x, y, _parent in ws.visible():
        state = tuple(v for k, v in sorted(obj.attrs.items())
                      if k not in ("raw_data", "children"))
        extra: object = None
        if "variable_reference" in obj.attrs:
            extra = ws.number(obj) if obj.type not in (T.OUTPUT_STRING, T.INPUT_STRING) \
                else ws.text(obj)
        out.append((obj.object_id, x, y, state, extra))
    return tuple(out)


__all__ = ["FONT_SIZES", "PALETTE", "colour", "decode_text", "number_text", "picture_pixels",
           "render", "visible_signature"]
