"""Per-run figures: step responses, field runs against truth, and the main panel of the rest.

Which traces: the rig's ``plot_groups``. The first group is the run's main signal; its traces
are told apart by name: ``target``/``setpoint`` is the setpoint, ``sensed`` what the DUT sees,
anything else the true (plant) signal. Groups whose title says ``truth`` go with field runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hil.report.figures import (
    COLORS,
    LABEL_PT,
    TEXT_PT,
    TITLE_PT,
    Image,
    decimate,
    new_figure,
    to_image,
)
from hil.report.rundata import RunData

BAND_FRACTION = 0.05


@dataclass
class RunPlot:
    run: RunData
    kind: str  # step | field | other
    image: Image | None = None
    notes: list[str] = field(default_factory=list)


def signal_role(name: str) -> str:
    lowered = name.lower()
    if "target" in lowered or "setpoint" in lowered:
        return "setpoint"
    if "sensed" in lowered:
        return "sensed"
    return "truth"


def classify(run: RunData) -> str:
    """step | field | other, from the run's measurements, else its scenario's name."""
    names = [m.name for m in run.measurements]
    if any(".step." in n for n in names):
        return "step"
    if any(".field." in n for n in names):
        return "field"
    words = run.scenario.lower().replace("_", "-").split("-")
    if "step" in words:
        return "step"
    if words and words[0] == "field":
        return "field"
    return "other"


_STYLE: dict[str, dict[str, Any]] = {
    "truth": {"lw": 0.9, "alpha": 0.75, "zorder": 2},
    "sensed": {"lw": 1.2, "zorder": 3},
    "setpoint": {"lw": 1.2, "ls": "--", "zorder": 4},
}


def _plot_group(ax: Any, run: RunData, title: str, signals: list[str], sl: slice,
                notes: list[str]) -> list[str]:
    """Draw the group's traces (truth first, setpoint on top); returns the names drawn."""
    assert run.traces is not None
    t = run.traces["time_s"][sl]
    present = []
    for name in signals:
        if name in run.traces:
            present.append(name)
        else:
            notes.append(f"trace {name!r} (plot group {title!r}) is not in "
                         f"{run.ref.dir}/traces.npz")
    order = {"truth": 0, "sensed": 1, "setpoint": 2}
    for name in sorted(present, key=lambda n: order[signal_role(n)]):
        role = signal_role(name)
        unit = run.units.get(name, "")
        label = f"{'true' if role == 'truth' else role}: {name}" + (f" [{unit}]" if unit else "")
        ax.plot(t, run.traces[name][sl], color=COLORS[role] if role != "truth" else None,
                label=label, **_STYLE[role])
    ax.set_title(title, fontsize=TITLE_PT, loc="left")
    return present


def _event_text(event: dict[str, Any]) -> str:
    kind = str(event.get("kind") or "")
    detail = str(event.get("detail") or "").removesuffix(" on None")
    if kind == "fault":
        text = detail
    elif kind == "fault-cleared":
        text = f"cleared: {detail}"
    else:
        text = f"{kind}: {detail}" if detail else kind
    return text[:40]


def _mark_events(ax: Any, run: RunData) -> None:
    """Faults and other non-setpoint events as dotted lines with their text (staggered, so
    a fault and its clearing a few seconds apart stay readable)."""
    k = 0
    for event in run.events:
        if event.get("kind") == "set" or not isinstance(event.get("t"), int | float):
            continue
        ax.axvline(float(event["t"]), color="#555555", ls=":", lw=1.0, zorder=1)
        ax.annotate(_event_text(event), (float(event["t"]), 1.0),
                    xycoords=("data", "axes fraction"), xytext=(3, -10 - 9 * (k % 3)),
                    textcoords="offset points", fontsize=TEXT_PT, color="#444444",
                    bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none",
                          "alpha": 0.8})
        k += 1


def _step_times(t: np.ndarray, setpoint: np.ndarray) -> list[float]:
    finite = np.isfinite(setpoint)
    scale = max(1.0, float(np.abs(setpoint[finite]).max())) if finite.any() else 1.0
    idx = np.flatnonzero(np.abs(np.diff(setpoint)) > 1e-9 * scale)
    return [float(t[i + 1]) for i in idx]


def _mark_response_times(ax: Any, run: RunData, steps: list[float], notes: list[str]) -> None:
    """Each ``*response_time`` measurement at its step (``conditions.step_at_s`` when given,
    else the n-th setpoint step for the n-th measurement of that name)."""
    seen: dict[str, int] = {}
    for m in run.measurements:
        if not m.name.endswith("response_time"):
            continue
        k = seen.get(m.name, 0)
        seen[m.name] = k + 1
        at = m.conditions.get("step_at_s")
        t_step = float(at) if isinstance(at, int | float) else (
            steps[k] if k < len(steps) else None)
        value = m.numeric_value
        if t_step is None or value is None:
            notes.append(f"{m.name} ({m.conditions_label or 'no conditions'}) not marked: "
                         + ("no value" if value is None else "step time unknown"))
            continue
        color = COLORS["sensed"] if "sensed" in m.name else COLORS["truth"]
        label = "sensed" if "sensed" in m.name else "true"
        ax.axvline(t_step + value, color=color, lw=1.6, zorder=5,
                   label=f"{label} response {value:.3g} {m.unit}")
        if m.high is not None:
            ax.axvline(t_step + m.high, color=COLORS["limit"], lw=1.0, ls="-.", zorder=5,
                       label=f"limit {m.high:.3g} {m.unit}")


def _main_panel(ax: Any, run: RunData, sl: slice, notes: list[str],
                *, band: bool) -> bool:
    title, signals = run.plot_groups[0]
    present = _plot_group(ax, run, title, signals, sl, notes)
    if not present:
        return False
    setpoints = [n for n in present if signal_role(n) == "setpoint"]
    if band and setpoints:
        assert run.traces is not None
        t = run.traces["time_s"]
        sp = run.traces[setpoints[0]]
        ax.fill_between(t[sl], (sp * (1 - BAND_FRACTION))[sl], (sp * (1 + BAND_FRACTION))[sl],
                        color=COLORS["band"], alpha=0.45, lw=0, zorder=1, label="±5 % band")
        _mark_response_times(ax, run, _step_times(t, sp), notes)
    elif band:
        notes.append(f"no setpoint trace in plot group {title!r}: no ±5 % band")
    _mark_events(ax, run)
    return True


def _truth_depth_panel(ax: Any, run: RunData) -> None:
    assert run.truth is not None
    distance = np.asarray(run.truth["distance_m"], dtype=float)
    depth = np.asarray(run.truth["depth_mm"], dtype=float)
    if depth.ndim == 1:
        depth = depth[:, None]
    sl = decimate(distance.size)
    ax.fill_between(distance[sl], depth.min(axis=1)[sl], depth.max(axis=1)[sl],
                    color=COLORS["truth"], alpha=0.2, lw=0, label="row min-max (truth)")
    ax.plot(distance[sl], depth.mean(axis=1)[sl], color=COLORS["truth"], lw=0.9,
            label=f"mean of {depth.shape[1]} rows (truth)")
    traces = run.traces or {}
    setpoints = [n for n in traces if signal_role(n) == "setpoint" and n.endswith("_mm")]
    if "distance_m" in traces and setpoints:
        ax.plot(traces["distance_m"], traces[setpoints[0]], color=COLORS["setpoint"], ls="--",
                lw=1.2, label=setpoints[0])
    ax.set_title("true seed depth along the row (truth.npz)", fontsize=TITLE_PT, loc="left")
    ax.set_xlabel("distance [m]", fontsize=LABEL_PT)
    ax.set_ylabel("mm", fontsize=LABEL_PT)


def _finish(axes: Any, xlabel_axis: Any) -> None:
    xlabel_axis.set_xlabel("time [s]", fontsize=LABEL_PT)
    for ax in axes:
        if ax.has_data():
            # below the panel (a legend inside would hide the step it explains), clear of the
            # tick labels and the axis label: the pad is in font sizes, whatever the height
            ax.legend(fontsize=TEXT_PT, loc="upper left", bbox_to_anchor=(0.0, 0.0), ncol=2,
                      borderaxespad=4.2 if ax.get_xlabel() else 2.4, frameon=False,
                      handlelength=1.8, columnspacing=1.2)


def plot_run(run: RunData) -> RunPlot:
    kind = classify(run)
    out = RunPlot(run=run, kind=kind)
    if run.traces is None:
        return out
    if not run.plot_groups:
        out.notes.append(f"rig {run.rig!r} declares no plot groups: no plot of this run")
        return out
    sl = decimate(run.traces["time_s"].size)
    extra = [g for g in run.plot_groups[1:] if "truth" in g[0].lower()] if kind == "field" else []
    depth_truth = (kind == "field" and run.truth is not None
                   and {"distance_m", "depth_mm"} <= set(run.truth))
    panels = 1 + len(extra) + int(depth_truth)
    with new_figure(panels, sharex=False) as (fig, axes):
        drew = _main_panel(axes[0], run, sl, out.notes, band=kind == "step")
        for ax, (group_title, signals) in zip(axes[1:], extra, strict=False):
            _plot_group(ax, run, group_title, signals, sl, out.notes)
            _mark_events(ax, run)
        if depth_truth:
            _truth_depth_panel(axes[-1], run)
        if not drew and panels == 1:
            out.notes.append("none of the main plot group's traces is in traces.npz")
            return out
        time_axes = axes[: 1 + len(extra)]
        for ax in time_axes[1:]:
            ax.sharex(time_axes[0])
        _finish(axes, time_axes[-1])
        out.image = to_image(fig, f"{kind} run {run.ref.dir}: {run.scenario}")
    return out
