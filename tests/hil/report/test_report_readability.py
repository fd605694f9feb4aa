"""The report reads right (#20.7): chips that add up, figures for a 1400 px page and HiDPI
with readable text, and per-condition values as dots against their limits (no zoomed bars)."""

from __future__ import annotations

import base64
import io
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import hil.report.figures as figures
import hil.report.plots_runs as plots_runs
import hil.report.plots_summary as plots_summary
from hil.report.record import MeasurementRow

from .conftest import Page


def _realtime_timing() -> dict[str, Any]:
    return {"mode": "realtime", "period_s": 0.001, "ticks": 8000, "valid": True,
            "lateness_p50_s": 2e-6, "lateness_p99_s": 4e-5, "lateness_p999_s": 9e-5,
            "lateness_max_s": 2e-4, "miss_threshold_s": 5e-4,
            "histogram_edges_s": [0.0, 1e-6, 1e-5, 1e-4, 1e-3],
            "histogram_counts": [5000, 2900, 90, 10]}


@pytest.fixture
def rendered(make_qual_dir: Callable[..., Path], base_record: dict[str, Any],
             monkeypatch: pytest.MonkeyPatch) -> tuple[str, list[dict[str, Any]]]:
    """The report of the synthetic record (with a real-time histogram), and for every figure
    the sizes of its texts (pt) as they were rendered."""
    from hil.report import write_html

    seen: list[dict[str, Any]] = []
    original = figures.to_image

    def spy(fig: Any, alt: str) -> figures.Image:
        from matplotlib.legend import Legend
        from matplotlib.text import Text

        texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
        legends = [t for legend in fig.findobj(Legend) for t in legend.get_texts()]
        seen.append({"alt": alt, "sizes": [t.get_fontsize() for t in texts],
                     "legend_sizes": [t.get_fontsize() for t in legends]})
        return original(fig, alt)

    monkeypatch.setattr(plots_runs, "to_image", spy)
    monkeypatch.setattr(plots_summary, "to_image", spy)
    base_record["timing"] = _realtime_timing()
    html = write_html(make_qual_dir(base_record)).read_text(encoding="utf-8")
    return html, seen


def test_verdict_chips_add_up_to_the_measurements(rendered: tuple[str, list]) -> None:
    html, _ = rendered
    chips = {key: int(n) for key, n in
             re.findall(r'<span class="chip c-([a-z]+)"><b>(\d+)</b>', html)}
    rows = [cls for cls, _ in Page(html).tables["measurements"] if cls.startswith("m-")]
    assert sum(chips.values()) == len(rows) == 7
    assert chips["marginal"] == 1 and chips["pass"] == 2      # the marginal one only once


def test_figures_fit_a_1400px_page_at_2x(rendered: tuple[str, list]) -> None:
    from PIL import Image as PilImage

    html, _ = rendered
    images = Page(html).images
    assert len(images) >= 4
    for img in images:
        width, height = int(img["width"]), int(img["height"])
        # two side by side on a 1400 px page (24 px padding each side, 14 px gap)
        assert 600 <= width <= (1400 - 48 - 14) / 2 + 20, img["alt"]
        data = base64.b64decode(img["src"].split(",", 1)[1])
        with PilImage.open(io.BytesIO(data)) as png:
            assert png.size == (figures.SCALE * width, figures.SCALE * height), img["alt"]


def test_every_figure_text_is_readable(rendered: tuple[str, list]) -> None:
    _, seen = rendered
    assert len(seen) >= 4
    assert any(f["legend_sizes"] for f in seen), "the check covers legends"
    for fig in seen:
        smallest_css_px = min(fig["sizes"]) / 72.0 * figures.CSS_PX_PER_IN
        assert smallest_css_px >= figures.MIN_TEXT_CSS_PX, (fig["alt"], min(fig["sizes"]))


def _row(value: float | None, *, high: float | None = 1.5, low: float | None = None,
         speed: float = 0.0, outcome: str = "pass") -> MeasurementRow:
    return MeasurementRow(name="depth.step.response_time", value=value, unit="s", low=low,
                          high=high, conditions={"speed_kmh": speed}, outcome=outcome,
                          marginal=False, note="", test="t", run="r")


def _chart(rows: list[MeasurementRow]) -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    plots_summary.draw_condition_chart(ax, rows)
    plt.close(fig)
    return ax


def test_close_values_are_dots_on_an_axis_that_holds_the_limit() -> None:
    rows = [_row(v, speed=s) for v, s in ((1.19, 3), (1.2, 5), (1.215, 7))]
    ax = _chart(rows)
    assert not ax.containers, "no bars"
    lo, hi = ax.get_ylim()
    assert lo < 1.19 and hi > 1.5                           # the limit is on the axis
    assert (1.215 - 1.19) / (hi - lo) < 0.1                 # a 0.025 s spread looks small
    dots = [line for line in ax.get_lines() if line.get_marker() == "o"]
    assert [float(d.get_ydata()[0]) for d in dots] == [1.19, 1.2, 1.215]


def test_without_limits_the_axis_is_not_zoomed_into_noise() -> None:
    rows = [_row(v, high=None, speed=s, outcome="info") for v, s in ((1.19, 3), (1.2, 5))]
    lo, hi = _chart(rows).get_ylim()
    assert (1.2 - 1.19) / (hi - lo) < 0.1


def test_a_missing_value_is_marked_not_dropped() -> None:
    ax = _chart([_row(1.2), _row(None, outcome="error", speed=5)])
    crosses = [line for line in ax.get_lines() if line.get_marker() == "x"]
    assert len(crosses) == 1
    assert any("error" in t.get_text() for t in ax.texts)
    assert np.isfinite(ax.get_ylim()).all()
