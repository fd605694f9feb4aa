"""Shared helpers of the metric modules: input checks and result serialisation."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np


def as_time(t: Any, name: str = "t") -> np.ndarray:
    """``t`` as a 1-D float array, finite and strictly increasing (else ``ValueError``)."""
    arr = np.asarray(t, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    if arr.size and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite values")
    if arr.size > 1 and not np.all(np.diff(arr) > 0):
        raise ValueError(f"{name} must be strictly increasing")
    return arr


def plain(value: Any) -> Any:
    """A JSON-friendly copy: numpy scalars and arrays to Python, NaN kept as ``float('nan')``."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, list)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if hasattr(value, "to_dict"):
        return value.to_dict()
    return value


class DictMixin:
    """``to_dict()`` for the frozen result dataclasses (field order kept, arrays to lists)."""

    def to_dict(self) -> dict[str, Any]:
        return {f.name: plain(getattr(self, f.name)) for f in fields(self)}  # type: ignore[arg-type]


def sample_trace(t: np.ndarray, y: np.ndarray, x: np.ndarray, kind: str) -> np.ndarray:
    """Values of the trace ``y(t)`` (shape (n,) or (n, k)) at the times ``x``.

    ``kind="linear"`` interpolates between samples; ``"previous"`` holds each sample until the
    next (a setpoint log). ``x`` must lie within ``[t[0], t[-1]]``.
    """
    x = np.asarray(x, dtype=float)
    if x.size and (x.min() < t[0] or x.max() > t[-1]):
        raise ValueError(f"times {x.min():g}..{x.max():g} s lie outside the trace "
                         f"({t[0]:g}..{t[-1]:g} s)")
    if kind == "previous":
        idx = np.clip(np.searchsorted(t, x, side="right") - 1, 0, t.size - 1)
        return y[idx]
    if kind == "linear":
        if y.ndim == 1:
            return np.interp(x, t, y)
        return np.stack([np.interp(x, t, y[:, j]) for j in range(y.shape[1])], axis=-1)
    raise ValueError(f"unknown interpolation {kind!r} (linear, previous)")
