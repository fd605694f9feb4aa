"""Small HTML builders: every piece of text that reaches the page goes through :func:`esc`."""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from pathlib import PurePosixPath
from typing import Any
from urllib.parse import quote

from hil.report.figures import Image

DASH = "—"


def esc(value: Any) -> str:
    return html.escape("" if value is None else str(value), quote=True)


def fmt_num(value: Any) -> str:
    """Numbers with at least four significant digits, never in exponent form below 1e9."""
    if value is None:
        return DASH
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}" if abs(value) >= 10_000 else str(value)
    if not math.isfinite(value):
        return str(value)
    if value == 0:
        return "0"
    magnitude = abs(value)
    if 1e-4 <= magnitude < 1e9:
        digits = max(4, math.floor(math.log10(magnitude)) + 1)
        return f"{value:.{digits}g}"
    return f"{value:.4g}"


def fmt_seconds(value: float | None) -> str:
    return DASH if value is None else f"{value:.3g} s" if value < 100 else f"{value:,.0f} s"


def badge(status: str, text: str | None = None) -> str:
    """A coloured label; the class is the status with anything odd replaced."""
    cls = "".join(c if c.isalnum() else "-" for c in status.lower()) or "unknown"
    return f'<span class="badge b-{cls}">{esc(text or status.upper())}</span>'


def table(headers: Sequence[str], rows: Iterable[str], cls: str = "") -> str:
    head = "".join(f"<th>{esc(h)}</th>" for h in headers)
    body = "\n".join(rows)
    return (f'<table class="{esc(cls)}"><thead><tr>{head}</tr></thead>\n'
            f"<tbody>\n{body}\n</tbody></table>")


def row(cells: Sequence[str], cls: str = "") -> str:
    """A table row of already-escaped cells."""
    attr = f' class="{esc(cls)}"' if cls else ""
    return f"<tr{attr}>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"


def deflist(items: Sequence[tuple[str, str]]) -> str:
    """A definition list of (label, already-escaped value)."""
    body = "".join(f"<dt>{esc(k)}</dt><dd>{v}</dd>" for k, v in items)
    return f"<dl>{body}</dl>"


def relative_href(path: str) -> str | None:
    """A relative link inside the qualification directory, or None for anything else."""
    pure = PurePosixPath(path.replace("\\", "/"))
    if not path or pure.is_absolute() or ".." in pure.parts or ":" in path:
        return None
    return quote(str(pure), safe="/-_.~")


def link(path: str, text: str) -> str:
    href = relative_href(path)
    return f'<a href="{esc(href)}">{esc(text)}</a>' if href else esc(text)


def figure(image: Image, caption: str = "") -> str:
    cap = f"<figcaption>{caption}</figcaption>" if caption else ""
    size = (f' width="{image.width}" height="{image.height}"'
            if image.width and image.height else "")
    return (f'<figure><img alt="{esc(image.alt)}"{size} src="{image.uri}">{cap}</figure>')


def note(text: str) -> str:
    return f'<p class="note">{esc(text)}</p>'


def pre(text: str) -> str:
    return f"<pre>{esc(text)}</pre>"
