"""Summary figures: one measurement across its conditions, and the bench timing histogram."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from hil.report.figures import COLORS, LABEL_PT, TEXT_PT, TITLE_PT, Image, new_figure, to_image
from hil.report.record import MeasurementRow


def _chart_order(name: str) -> tuple[int, str]:
    lead = any(key in name for key in ("accuracy", "pass_rate"))
    return (0 if lead else 1, name)


def by_name(measurements: list[MeasurementRow]) -> list[tuple[str, list[MeasurementRow]]]:
    """Measurements with at least two instances (conditions), accuracy and pass rate first."""
    groups: dict[str, list[MeasurementRow]] = defaultdict(list)
    for m in measurements:
        groups[m.name].append(m)
    return sorted(((n, ms) for n, ms in groups.items() if len(ms) >= 2),
                  key=lambda item: _chart_order(item[0]))


def _draw_limits(ax: Any, ms: list[MeasurementRow], x: np.ndarray) -> None:
    """Dashed red limit lines, labelled at their right end (a legend would cover bars)."""
    for attr in ("low", "high"):
        limits = [getattr(m, attr) for m in ms]
        if all(v is None for v in limits):
            continue
        if len(set(limits)) == 1:
            ax.axhline(limits[0], color=COLORS["limit"], ls="--", lw=1.2, zorder=3)
            ax.annotate(f"{attr} limit {limits[0]:g}", (1.0, limits[0]),
                        xycoords=("axes fraction", "data"), xytext=(-2, 2),
                        textcoords="offset points", ha="right", va="bottom", fontsize=TEXT_PT,
                        color=COLORS["limit"], zorder=4,
                        bbox={"boxstyle": "square,pad=0.15", "fc": "white", "ec": "none",
                              "alpha": 0.85})
            continue
        for xi, v in zip(x, limits, strict=True):
            if v is not None:
                ax.hlines(v, xi - 0.4, xi + 0.4, color=COLORS["limit"], ls="--", lw=1.2,
                          zorder=3)


def tick_labels(ms: list[MeasurementRow]) -> tuple[list[str], str]:
    """Tick labels and the axis label: with one shared condition key, its values under the key's
    name; else every ``key=value`` on its own line."""
    keys = {tuple(sorted(m.conditions)) for m in ms}
    if len(keys) == 1 and len(next(iter(keys))) == 1:
        key = next(iter(keys))[0]
        return [str(m.conditions[key]) for m in ms], key
    labels = ["\n".join(f"{k}={m.conditions[k]}" for k in sorted(m.conditions))
              or m.test_name or f"#{i + 1}" for i, m in enumerate(ms)]
    return labels, ""


def value_axis(ms: list[MeasurementRow], values: list[float | None]) -> tuple[float, float]:
    """The value axis of a per-condition chart: every value and every limit on it, so each
    value is seen at the scale of its distance to the limit (a 0.01 s spread against a limit
    0.3 s away stays small). Without limits the axis is at least 20 % of the values'
    magnitude wide, so noise-level differences do not fill it."""
    points = [v for v in values if v is not None and np.isfinite(v)]
    limits = [v for m in ms for v in (m.low, m.high) if v is not None and np.isfinite(v)]
    every = points + limits
    if not every:
        return 0.0, 1.0
    lo, hi = min(every), max(every)
    magnitude = max(abs(lo), abs(hi))
    floor = (0.05 if limits else 0.2) * magnitude or 1.0
    span = max(hi - lo, floor)
    mid = (lo + hi) / 2.0
    lo, hi = min(lo, mid - span / 2.0), max(hi, mid + span / 2.0)
    pad = 0.12 * (hi - lo)
    return lo - pad, hi + pad


def _shade_pass_band(ax: Any, ms: list[MeasurementRow], x: np.ndarray,
                     axis: tuple[float, float]) -> None:
    """The values that pass, lightly shaded per condition: from the low limit (or the axis
    bottom) to the high limit (or the axis top)."""
    for xi, m in zip(x, ms, strict=True):
        if m.low is None and m.high is None:
            continue
        bottom = axis[0] if m.low is None else m.low
        top = axis[1] if m.high is None else m.high
        ax.fill_between([xi - 0.45, xi + 0.45], bottom, top, color=COLORS["band"],
                        alpha=0.35, lw=0, zorder=1)


def draw_condition_chart(ax: Any, ms: list[MeasurementRow]) -> None:
    """Dots for the values against their limits on ``ax`` (no bars: a bar's length on an axis
    that does not start at 0 misleads)."""
    values = [m.numeric_value for m in ms]
    x = np.arange(len(ms), dtype=float)
    axis = value_axis(ms, values)
    _shade_pass_band(ax, ms, x, axis)
    _draw_limits(ax, ms, x)
    for xi, v, m in zip(x, values, ms, strict=True):
        bad = m.status in ("fail", "error")
        if v is None or not np.isfinite(v):
            ax.plot([xi], [axis[0]], marker="x", ms=9, mew=2, color=COLORS["error"],
                    zorder=5, clip_on=False)
            ax.annotate("error: no value", (xi, axis[0]), xytext=(0, 6),
                        textcoords="offset points", ha="center", va="bottom",
                        fontsize=TEXT_PT, color=COLORS["error"], fontweight="bold")
            continue
        ax.plot([xi], [v], marker="o", ms=9, color=COLORS[m.status], mec="#222222",
                mew=0.8, zorder=5, ls="none")
        ax.annotate(f"{v:.4g}", (xi, v), xytext=(9, 0), textcoords="offset points",
                    ha="left", va="center", fontsize=TEXT_PT, color="#222222",
                    fontweight="bold" if bad else "normal")
    ax.set_ylim(*axis)
    ax.set_xlim(-0.6, len(ms) - 0.4)


def condition_chart(name: str, ms: list[MeasurementRow]) -> Image:
    """One measurement across its conditions: dots against the limits and the pass band."""
    labels, xlabel = tick_labels(ms)
    x = np.arange(len(ms), dtype=float)
    with new_figure(1, sharex=False) as (fig, axes):
        ax = axes[0]
        draw_condition_chart(ax, ms)
        crowded = sum(len(max(label.split("\n"), key=len)) for label in labels) > 60
        ax.set_xticks(x, labels, fontsize=TEXT_PT, rotation=25 if crowded else 0,
                      ha="right" if crowded else "center")
        if xlabel:
            ax.set_xlabel(xlabel, fontsize=LABEL_PT)
        unit = ms[0].unit
        ax.set_ylabel(unit, fontsize=LABEL_PT)
        ax.set_title(f"{name} [{unit}]", fontsize=TITLE_PT, loc="left")
        return to_image(fig, f"{name} per condition")


_LINES = (("lateness_p50_s", "p50", "#2e8b3e"), ("lateness_p99_s", "p99", "#d4a000"),
          ("lateness_p999_s", "p99.9", "#e07b00"), ("lateness_max_s", "max", "#c62828"))


def timing_histogram(timing: dict[str, Any]) -> Image | None:
    """Lateness histogram of a real-time run (None without one)."""
    edges = np.asarray(timing.get("histogram_edges_s") or [], dtype=float)
    counts = np.asarray(timing.get("histogram_counts") or [], dtype=float)
    if edges.size < 2 or counts.size != edges.size - 1:
        return None
    edges_us = edges * 1e6
    with new_figure(1, height=2.9, sharex=False) as (fig, axes):
        ax = axes[0]
        # a log count axis: fill down to 0.8 so that empty bins stay empty
        ax.stairs(np.maximum(counts, 0.8), edges_us, baseline=0.8, fill=True,
                  color="#7aa6d6", zorder=2)
        for key, label, color in _LINES:
            value = timing.get(key)
            if isinstance(value, int | float):
                ax.axvline(value * 1e6, color=color, lw=1.2,
                           label=f"{label} {value * 1e6:.1f} µs")
        threshold = timing.get("miss_threshold_s")
        if isinstance(threshold, int | float) and threshold > 0:
            ax.axvline(threshold * 1e6, color="#555555", ls="--", lw=1.0,
                       label=f"miss threshold {threshold * 1e6:.0f} µs")
        ax.set_xscale("symlog", linthresh=1.0)
        ax.set_xlim(0.0, edges_us[-1] * 1.1)
        ax.set_yscale("log")
        ax.set_ylim(0.8, max(float(counts.max()), 1.0) * 2.0)
        ax.set_xlabel("lateness of a tick [µs]", fontsize=LABEL_PT)
        ax.set_ylabel("ticks", fontsize=LABEL_PT)
        ax.set_title("bench timing: lateness of the rig's ticks (worst run)", fontsize=TITLE_PT,
                     loc="left")
        ax.legend(fontsize=TEXT_PT, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        return to_image(fig, "timing histogram of tick lateness")
