"""Per-measurement distribution figure of a campaign: histogram and ECDF against the limits."""

from __future__ import annotations

import numpy as np

from hil.report.figures import COLORS, Image, new_figure, to_image


def distribution_image(key: str, values: list[float], *, low: float | None,
                       high: float | None, unit: str | None) -> Image | None:
    """Histogram (left) and empirical CDF (right) of ``values`` with the limits drawn in."""
    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if x.size == 0:
        return None
    import matplotlib.pyplot as plt

    with new_figure(1, width=9.0, height=2.6) as (fig, axes):
        fig.delaxes(axes[0])
        hist, ecdf = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
        hist.hist(x, bins=min(40, max(5, int(np.sqrt(x.size)) * 2)), color=COLORS["truth"],
                  alpha=0.8)
        xs = np.sort(x)
        ecdf.step(xs, np.arange(1, xs.size + 1) / xs.size, where="post",
                  color=COLORS["truth"])
        for ax in (hist, ecdf):
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=8)
            for limit in (low, high):
                if limit is not None:
                    ax.axvline(limit, color=COLORS["limit"], linestyle="--", linewidth=1.2)
            ax.set_xlabel(f"{key} [{unit or ''}]", fontsize=8)
        hist.set_ylabel("samples", fontsize=8)
        ecdf.set_ylabel("fraction <= x", fontsize=8)
        image = to_image(fig, f"{key}: {x.size} samples, histogram and ECDF, limits dashed")
    plt.close("all")
    return image
