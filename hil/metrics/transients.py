"""Mass error during speed transients, as seconds of the flow change.

How much a flow controller's delivery lags (or leads) its target while the ground speed
changes.

In the field the target flow follows ground speed ([F] eq. 1, ``Q = 0.1·M·D·v``). A
controller that follows a change of ``Q`` by ``ΔQ`` with a lag of ``τ`` seconds (a pure delay,
or a first-order low-pass of time constant ``τ``) delivers ``τ·ΔQ`` grams too few while the
flow rises and as many too many while it falls, and that mass is never made up. Over windows
that each hold one transient and its settling,

    lag = Σ_i |∫_{W_i} (delivered - target) dt| / Σ_i |ΔQ_i|   (s),

which reads ``τ`` for any such lag whatever the shape and length of the transients, so its
limit does not depend on the scenario. ``ΔQ_i`` is the change of the target between the
ends of window ``i`` (means over ``edge_s`` at each end). The windows must each be long enough
for the slowest lag of interest to settle: ~3 τ after the speed has settled.

The mass error as a percentage of the target mass in the windows is returned alongside, as
the figure a field agronomist reads.

>>> import numpy as np
>>> t = np.arange(0.0, 30.0, 0.01)
>>> q = np.interp(t, [0, 10, 12, 30], [20.0, 20.0, 30.0, 30.0])
>>> late = np.interp(t - 0.5, t, q)                # the same flow 0.5 s late
>>> round(transient_lag(t, late, q, [(9.0, 20.0)]).lag_s, 3)
0.5
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hil.metrics._common import DictMixin, as_time

__all__ = ["TransientLag", "transient_lag"]


@dataclass(frozen=True)
class TransientLag(DictMixin):
    """Result of :func:`transient_lag`."""

    lag_s: float
    """``Σ abs(mass error) / Σ abs(ΔQ)`` over the windows (s): a pure lag τ reads τ."""
    mass_error_pct: float
    """``Σ abs(mass error) / Σ target mass`` over the windows, %."""
    window_errors_g: tuple[float, ...]
    """Signed mass error (delivered - target) per window (the flows' unit times s: g)."""
    window_steps_gps: tuple[float, ...]
    """Signed change of the target flow across each window."""


def _mean_between(t: np.ndarray, y: np.ndarray, a: float, b: float) -> float:
    sel = (t >= a) & (t <= b)
    if not sel.any():
        raise ValueError(f"no samples between {a:g} and {b:g} s")
    return float(np.mean(y[sel]))


def transient_lag(t: np.ndarray, delivered: np.ndarray, target: np.ndarray,
                  windows: list[tuple[float, float]], *, edge_s: float = 0.5) -> TransientLag:
    """The lag equivalent of the mass error of ``delivered`` against ``target``.

    ``delivered`` and ``target`` are flows in the same unit, sampled at ``t``; each of the
    ``windows`` ((start, end) in s) holds one change of the target and its settling.

    Raises
    ------
    ValueError
        On mismatched shapes, no windows, a window outside the record, or a total target change
        of zero (nothing to lag behind).
    """
    t = as_time(t)
    d = np.asarray(delivered, dtype=float)
    q = np.asarray(target, dtype=float)
    if d.shape != t.shape or q.shape != t.shape:
        raise ValueError(f"t, delivered and target need one shape: {t.shape}, {d.shape}, "
                         f"{q.shape}")
    if not windows:
        raise ValueError("no transient windows")
    errors, steps, masses = [], [], []
    for a, b in windows:
        if not t[0] <= a < b <= t[-1]:
            raise ValueError(f"window {a:g}..{b:g} s is not inside the record "
                             f"({t[0]:g}..{t[-1]:g} s)")
        sel = (t >= a) & (t <= b)
        errors.append(float(np.trapezoid(d[sel] - q[sel], t[sel])))
        masses.append(float(np.trapezoid(q[sel], t[sel])))
        steps.append(_mean_between(t, q, b - edge_s, b) - _mean_between(t, q, a, a + edge_s))
    total_step = sum(abs(s) for s in steps)
    if total_step <= 0:
        raise ValueError("the target does not change in any window")
    total_error = sum(abs(e) for e in errors)
    return TransientLag(total_error / total_step, 100.0 * total_error / sum(masses),
                        tuple(errors), tuple(steps))
