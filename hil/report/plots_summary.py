"""Summary figures: one measurement across its conditions, and the bench timing histogram."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from hil.report.figures import COLORS, Image, new_figure, to_image
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
                        textcoords="offset points", ha="right", va="bottom", fontsize=7,
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


def _zoom(ax: Any, ms: list[MeasurementRow], values: list[float | None]) -> bool:
    """Zoom the value axis when everything sits far from zero (accuracies of 95-99 %); the
    bars then do not start at zero, which the title says."""
    points = [v for v in values if v is not None]
    points += [v for m in ms for v in (m.low, m.high) if v is not None]
    if not points or min(points) <= 0:
        return False
    lo, hi = min(points), max(points)
    if lo < 0.5 * hi:
        return False
    span = max(hi - lo, 0.02 * hi)
    ax.set_ylim(max(0.0, lo - 0.6 * span), hi + 0.35 * span)
    return True


def condition_chart(name: str, ms: list[MeasurementRow]) -> Image:
    labels, xlabel = tick_labels(ms)
    values = [m.numeric_value for m in ms]
    x = np.arange(len(ms), dtype=float)
    with new_figure(1, height=2.8, sharex=False) as (fig, axes):
        ax = axes[0]
        zoomed = _zoom(ax, ms, values)
        base = ax.get_ylim()[0] if zoomed else 0.0
        heights = [(v if v is not None else base) - base for v in values]
        ax.bar(x, heights, bottom=base, color=[COLORS[m.status] for m in ms], width=0.7,
               zorder=2)
        for xi, v, m in zip(x, values, ms, strict=True):
            ax.annotate("error" if v is None else f"{v:.4g}", (xi, base if v is None else v),
                        xytext=(0, 2), textcoords="offset points", ha="center", va="bottom",
                        fontsize=7, color=COLORS["error"] if v is None else "#222222",
                        fontweight="bold" if m.status in ("fail", "error") else "normal")
        _draw_limits(ax, ms, x)
        crowded = sum(len(max(label.split("\n"), key=len)) for label in labels) > 60
        ax.set_xticks(x, labels, fontsize=7, rotation=25 if crowded else 0,
                      ha="right" if crowded else "center")
        if xlabel:
            ax.set_xlabel(xlabel, fontsize=8)
        unit = ms[0].unit
        ax.set_ylabel(unit, fontsize=8)
        ax.set_title(f"{name} [{unit}]" + ("  (value axis does not start at 0)" if zoomed
                                           else ""), fontsize=9, loc="left")
        if not zoomed:
            ax.margins(y=0.15)
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
    with new_figure(1, width=7.0, height=2.8, sharex=False) as (fig, axes):
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
        ax.set_xlabel("lateness of a tick [µs]", fontsize=8)
        ax.set_ylabel("ticks", fontsize=8)
        ax.set_title("bench timing: lateness of the rig's ticks (worst run)", fontsize=9,
                     loc="left")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        return to_image(fig, "timing histogram of tick lateness")
