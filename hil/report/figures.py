"""Matplotlib (Agg) figures turned into inline ``data:`` URIs, kept small.

Sized for a 1400 px page (two figures side by side) and HiDPI screens: a figure is
:data:`WIDTH_IN` inches wide and shown at :data:`CSS_PX_PER_IN` CSS pixels per inch (680 px),
and its PNG has :data:`SCALE` (2) device pixels per CSS pixel, so it stays sharp on a 2x
screen and when zoomed. Text sizes are in points at that scale: :data:`TEXT_PT` (ticks,
legends, annotations: 12.5 CSS px), :data:`LABEL_PT` (axis labels), :data:`TITLE_PT`.
"""

from __future__ import annotations

import base64
import io
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: CSS pixels per inch of figure as the page shows it
CSS_PX_PER_IN = 100
#: device pixels per CSS pixel in the PNG (HiDPI)
SCALE = 2
DPI = CSS_PX_PER_IN * SCALE
#: most points a plotted trace keeps (a 60 s trace has 6,000 rows)
MAX_POINTS = 1200
WIDTH_IN = 6.8
PANEL_HEIGHT_IN = 2.9
#: text sizes (pt); at CSS_PX_PER_IN, 1 pt is 1.39 CSS px
TEXT_PT = 9.0
LABEL_PT = 10.0
TITLE_PT = 11.0
#: the smallest text a figure may have, in CSS px as shown (a test holds every figure to it)
MIN_TEXT_CSS_PX = 12.0

COLORS = {"setpoint": "#111111", "sensed": "#e07b00", "truth": "#1f5fbf", "other": "#6a3d9a",
          "pass": "#2e8b3e", "marginal": "#d4a000", "fail": "#c62828", "error": "#6d1b7b",
          "info": "#8a8a8a", "band": "#9ed39e", "limit": "#c62828"}


@dataclass(frozen=True)
class Image:
    """A rendered figure: its data URI, a text alternative, and its size on the page in CSS
    pixels (the PNG has :data:`SCALE` times as many device pixels)."""

    uri: str
    alt: str
    width: int = 0
    height: int = 0


def decimate(n: int, max_points: int = MAX_POINTS) -> slice:
    """A stride that keeps at most about ``max_points`` of ``n`` samples."""
    return slice(None, None, max(1, -(-n // max_points)))


@contextmanager
def new_figure(panels: int = 1, *, width: float = WIDTH_IN,
               height: float = PANEL_HEIGHT_IN, sharex: bool = True) -> Iterator[
                   tuple[Figure, Any]]:
    """A figure with ``panels`` stacked axes (an array of them); closed on exit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(panels, 1, figsize=(width, height * panels), sharex=sharex,
                             squeeze=False)
    try:
        for ax in axes[:, 0]:
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=TEXT_PT)
        yield fig, axes[:, 0]
    finally:
        plt.close(fig)


def to_image(fig: Figure, alt: str) -> Image:
    """PNG (no metadata, palette-quantized when Pillow allows) as a base64 data URI."""
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    data = _quantize(buf.getvalue())
    width_in, height_in = fig.get_size_inches()
    return Image(uri="data:image/png;base64," + base64.b64encode(data).decode("ascii"),
                 alt=alt, width=round(width_in * CSS_PX_PER_IN),
                 height=round(height_in * CSS_PX_PER_IN))


def _quantize(png: bytes) -> bytes:
    """An adaptive 128-colour palette: a third of the size, no visible loss on line plots."""
    try:
        from PIL import Image as PilImage
    except ImportError:  # pragma: no cover - Pillow ships with matplotlib
        return png
    with PilImage.open(io.BytesIO(png)) as im:
        out = io.BytesIO()
        im.convert("RGB").quantize(colors=128, method=PilImage.Quantize.MEDIANCUT).save(
            out, format="PNG", optimize=True)
    data = out.getvalue()
    return data if len(data) < len(png) else png
