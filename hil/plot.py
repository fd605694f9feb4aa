"""PNG plots of a run's traces: one panel per group the rig declares."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np


def plot_traces(arrays: dict[str, np.ndarray], units: dict[str, str],
                groups: Sequence[tuple[str, Sequence[str]]], path: Path, title: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(name, [s for s in signals if s in arrays]) for name, signals in groups]
    panels = [(name, signals) for name, signals in panels if signals]
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 2.6 * len(panels)), sharex=True,
                             squeeze=False)
    t = arrays["time_s"]
    for ax, (name, signals) in zip(axes[:, 0], panels, strict=True):
        for signal in signals:
            ax.plot(t, arrays[signal], label=f"{signal} [{units.get(signal, '')}]", lw=1.0)
        ax.set_title(name, fontsize=10, loc="left")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
