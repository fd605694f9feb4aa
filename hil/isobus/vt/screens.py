"""The screens the operator saw, drawn as they changed, and the VT's part of a run's record.

:class:`ScreenRecorder` listens to the VT (its ``on_change`` hooks) and draws the active
working set's screen (:func:`hil.isobus.vt.render.render`) whenever the active mask, the soft
key mask or a shown value changes: a new mask at once; value changes at most every
``min_interval_s`` of run time (the last change of a burst is always drawn, at the end of
the interval). A screen identical to the one before is not drawn again. Each screen is a PNG
(``screen-0001.png`` ...) in ``directory`` when one is given; the latest is kept in memory
for the browser VT either way.

:func:`vt_record` is the VT's part of a run's record: per working set its pool (size in bytes,
objects, the version label it was stored or loaded under, SHA-256 of its bytes, when it became
active and whether from storage), and the screens with their run times. The report draws the
screens on the run's time line from it (:mod:`hil.report.sections_vt`).
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from hil.isobus.vt.commands import is_enabled
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.render import GAP, render, visible_signature
from hil.isobus.vt.server import VirtualTerminalServer
from hil.isobus.vt.workingset import WorkingSet

SCREENS_DIR = "vt"
"""The run directory's folder for the screens and ``vt.json``."""


@dataclass(frozen=True)
class Screen:
    """One drawn screen."""

    time_s: float
    address: int
    mask: int
    soft_key_mask: int
    reason: str
    file: str
    sha256: str


class ScreenRecorder:
    """Draws the VT's screens as they change (see the module docstring).

    Parameters
    ----------
    vt : VirtualTerminalServer
        The VT to listen to.
    directory : Path, optional
        Where the PNGs go (created on the first screen); ``None``: kept in memory only.
    min_interval_s : float
        Least run time between two screens of value changes on the same mask.
    max_screens : int
        Screens kept at most (a run that changes its screen for hours keeps its first ones and
        counts the rest in :attr:`dropped`).
    keep_images : bool
        Keep every screen's PNG in :attr:`images` (by file name), for a run that has no
        directory to draw into (a rig's field run carries them in its record).
    """

    def __init__(self, vt: VirtualTerminalServer, directory: Path | None = None,
                 min_interval_s: float = 0.5, max_screens: int = 1000,
                 keep_images: bool = False) -> None:
        self.vt = vt
        self.directory = directory
        self.min_interval_s = min_interval_s
        self.max_screens = max_screens
        self.keep_images = keep_images
        #: the screens' PNGs by file name (with ``keep_images``)
        self.images: dict[str, bytes] = {}
        self.screens: list[Screen] = []
        self.dropped = 0
        #: the latest screen's PNG bytes per working set address
        self.latest_png: dict[int, bytes] = {}
        #: the latest screen per address as (count, PNG, hotspots), replaced whole (other
        #: threads read it: the browser VT)
        self.latest: dict[int, tuple[int, bytes, tuple[Hotspot, ...]]] = {}
        self.drawn = 0
        self._last: dict[int, tuple[float, tuple[object, ...], int]] = {}
        self._pending: set[int] = set()
        vt.on_change.append(self._on_change)

    def _on_change(self, ws: WorkingSet, time_s: float, reason: str) -> None:
        if reason == "VT restarted":
            # the restart drops the VT's timers, a deferred screen's with them
            self._pending.discard(ws.address)
            return
        if ws.pool is None or ws.locked_mask is not None:
            return
        last = self._last.get(ws.address)
        if last is not None and last[2] == ws.active_mask and \
                time_s - last[0] < self.min_interval_s - 1e-9:
            if ws.address not in self._pending:
                self._pending.add(ws.address)
                self.vt.at(last[0] + self.min_interval_s,
                           lambda now, a=ws.address: self._deferred(a, now))
            return
        self.draw(ws, time_s, reason)

    def _deferred(self, address: int, now: float) -> None:
        self._pending.discard(address)
        ws = self.vt.sessions.get(address)
        if ws is not None and ws.pool is not None and ws.locked_mask is None:
            self.draw(ws, now, "values changed")

    def draw(self, ws: WorkingSet, time_s: float, reason: str) -> Screen | None:
        """Draw the working set's screen now (unless it is the one drawn last)."""
        signature = visible_signature(ws)
        last = self._last.get(ws.address)
        if last is not None and last[1] == signature:
            return None
        self._last[ws.address] = (time_s, signature, ws.active_mask)
        o = self.vt.options
        image = render(ws, o.data_mask_px, o.soft_key_width_px, o.soft_key_height_px,
                       o.physical_soft_keys)
        png = png_bytes(image)
        self.latest_png[ws.address] = png
        self.drawn += 1
        self.latest[ws.address] = (self.drawn, png, hotspots(ws, o.data_mask_px,
                                                              o.soft_key_width_px,
                                                              o.soft_key_height_px,
                                                              o.physical_soft_keys))
        if len(self.screens) >= self.max_screens:
            self.dropped += 1
            return None
        name = f"screen-{len(self.screens) + 1:04d}.png"
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)
            (self.directory / name).write_bytes(png)
        if self.keep_images:
            self.images[name] = png
        screen = Screen(round(time_s, 6), ws.address, ws.active_mask, ws.soft_key_mask,
                        reason, name, hashlib.sha256(png).hexdigest())
        self.screens.append(screen)
        return screen


def png_bytes(image: Image.Image) -> bytes:
    """A screen as PNG: indexed with its own colours when it has 256 or fewer (a VT draws from
    the standard's 256), every pixel exactly its colour, about a third of the RGB PNG's size
    for ~10 ms more; else RGB as it is."""
    buffer = io.BytesIO()
    colours = image.getcolors(256) if image.mode == "RGB" else None
    if colours:
        keys = np.sort(np.array([(r << 16) | (g << 8) | b for _, (r, g, b) in colours],
                                dtype=np.uint32))
        rgb = np.asarray(image, dtype=np.uint32)
        packed = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
        indexed = Image.fromarray(np.searchsorted(keys, packed).astype(np.uint8), "P")
        indexed.putpalette(np.stack([keys >> 16, (keys >> 8) & 0xFF, keys & 0xFF],
                                    axis=1).astype(np.uint8).tobytes())
        indexed.save(buffer, format="PNG")
        return buffer.getvalue()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


@dataclass(frozen=True)
class Hotspot:
    """Where a soft key or button is on a screen, for pressing it in the browser."""

    object_id: int
    kind: str
    label: str
    x: int
    y: int
    w: int
    h: int
    enabled: bool = True


def hotspots(ws: WorkingSet, mask_px: int, key_w: int, key_h: int,
             keys: int) -> tuple[Hotspot, ...]:
    """The soft keys (in the column right of the mask) and the buttons shown on the mask."""
    out: list[Hotspot] = []
    skm = ws.resolve(ws.soft_key_mask)
    if skm is not None:
        for i, key_id in enumerate(skm["keys"][:keys]):
            key = ws.resolve(key_id)
            if key is not None and key.type == ObjectType.KEY:
                out.append(Hotspot(key.object_id, "key", ws.label(key.object_id),
                                   mask_px + GAP, i * (key_h + GAP), key_w, key_h))
    for obj, x, y, _parent in ws.visible(ws.active_mask):
        if obj.type == ObjectType.BUTTON and x < mask_px and y < mask_px:
            out.append(Hotspot(obj.object_id, "button", ws.label(obj.object_id), x, y,
                               obj["width"], obj["height"], is_enabled(obj)))
    return tuple(out)


def vt_record(vt: VirtualTerminalServer, recorder: ScreenRecorder | None = None,
              ) -> dict[str, Any]:
    """The VT's part of a run's record (JSON-ready)."""
    sets = []
    for a in vt.activations:
        entry = asdict(a)
        entry["name"] = f"{a.name:016X}" if a.name is not None else None
        entry["activated_s"] = entry.pop("time_s")
        ws = vt.sessions.get(a.address)
        entry["connected_at_end"] = ws is not None and ws.activated_s == a.time_s
        sets.append(entry)
    out: dict[str, Any] = {
        "vt_version": vt.options.version, "data_mask_px": vt.options.data_mask_px,
        "working_sets": sets,
        "events": [asdict(e) for e in vt.events],
        "commands": vt.counts["commands"],
        "command_errors": vt.counts["command errors"],
        "events_omitted": vt.events.omitted,
    }
    if recorder is not None:
        out["screens"] = [asdict(s) for s in recorder.screens]
        out["screens_dir"] = SCREENS_DIR
        out["screens_dropped"] = recorder.dropped
    return out


def write_vt_record(run_dir: Path, vt: VirtualTerminalServer,
                    recorder: ScreenRecorder | None = None) -> Path:
    """Write ``vt/vt.json`` in the run directory (the screens are there already when the
    recorder drew into ``run_dir / "vt"``)."""
    path = run_dir / SCREENS_DIR / "vt.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(vt_record(vt, recorder), indent=1), encoding="utf-8")
    tmp.replace(path)
    return path
