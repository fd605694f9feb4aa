"""What each row of a sectioned meter applied while it was meant to meter, and while it was not.

Rows switched on and off (the terminal's ActiveRows, or an ISOBUS Task Controller's section
control) share one physics: a row that should meter must lay its own target, a row that
should not must lay nothing. Given, per row,

- ``delivered_g``: the cumulative mass that has left its tube (what lands), sampled at ``t``;
- ``target_gps``: the flow it should meter now (0 where it should not);
- ``on``: whether it should meter now (the terminal's rows, the field's sections);

and the meter-to-ground transport ``transport_s`` (what is metered at ``t`` lands at
``t + transport_s``), the delivered trace is moved back by the transport and split by ``on``:

- **applied accuracy** of a row, [F] eq. 15 on its own mass: the mass it laid over the time
  it should meter against the integral of its target over that time;
- **off delivery** of a row: the mass it laid while it should not meter, from ``settle_s``
  after each switch-off (the granules still falling through the tube's dispersion when the
  roller stops belong to the metering before).

The run's last ``transport_s`` is not judged (what is metered there has not landed).

Rows metered by one shaft split what the controller meters by their rollers' gains, which no
controller changes: with ``row_gain`` given (the rig's truth), each row's target is the rows'
total target at each instant, split among the rows that should meter by their gains
(``g_j·Σ_on target / Σ_on g``). The controller then answers for what it can govern, the total
of the rows it meters and which rows meter, not the rollers' spread.

>>> import numpy as np
>>> t = np.arange(0.0, 20.0, 0.01)
>>> on = np.column_stack([np.ones_like(t, bool), t < 10.0])
>>> target = np.where(on, 10.0, 0.0)
>>> flow = np.where(on, 10.0, 0.0) * [1.0, 1.02]        # row 2 meters 2 % high
>>> late = np.vstack([np.zeros((50, 2)), flow[:-50]])   # lands 0.5 s later
>>> delivered = np.vstack([np.zeros((1, 2)), np.cumsum(late[:-1], axis=0) * 0.01])
>>> r = applied_per_row(t, delivered, target, on, transport_s=0.5)
>>> [round(a, 1) for a in r.accuracy_pct]
[100.0, 98.0]
>>> [round(g, 3) for g in r.off_delivery_g]     # row 1 never switched off
[nan, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hil.metrics._common import DictMixin
from hil.metrics.accuracy import accuracy_theta

__all__ = ["RowsApplied", "applied_per_row"]

#: after a row stops, what was already in its tube keeps landing for the tube's dispersion
#: (granules spread over a few hundredths of a second on the rig); 0.5 s clears it with margin
SETTLE_S = 0.5


@dataclass(frozen=True)
class RowsApplied(DictMixin):
    """Per row (row 1 first).

    nan where the row never should meter (accuracy) or never should not (off delivery).
    """

    accuracy_pct: tuple[float, ...]
    """[F] eq. 15 of the row's mass laid while it should meter against its target there."""
    laid_g: tuple[float, ...]
    """Mass the row laid while it should meter."""
    target_g: tuple[float, ...]
    """Its target over that time."""
    on_s: tuple[float, ...]
    """Time it should meter (judged part of the run)."""
    off_delivery_g: tuple[float, ...]
    """Mass it laid while it should not meter (from ``settle_s`` after each switch-off)."""
    off_s: tuple[float, ...]
    """Time it should not meter, judged (the settling excluded)."""


def applied_per_row(t: np.ndarray, delivered_g: np.ndarray, target_gps: np.ndarray,
                    on: np.ndarray, *, transport_s: float, settle_s: float = SETTLE_S,
                    row_gain: np.ndarray | None = None) -> RowsApplied:
    """Each row's accuracy while it should meter and mass laid while it should not (module).

    Parameters
    ----------
    t : (k,) array
        Sample times, s, increasing (evenly spaced).
    delivered_g : (k, s) array
        Cumulative mass delivered per row, g.
    target_gps : (k, s) array
        Each row's target flow, g/s.
    on : (k, s) bool array
        Whether each row should meter.
    transport_s : float
        Meter to ground, s (>= 0).
    settle_s : float
        Excluded from the off delivery after each switch-off, s.
    row_gain : (s,) array, optional
        The rollers' gains: split each instant's total target by them (see the module).

    Raises
    ------
    ValueError
        Shapes that do not match, fewer than two samples left once the transport is cut
        from the end, or a negative transport.
    """
    t = np.asarray(t, dtype=float)
    delivered = np.asarray(delivered_g, dtype=float)
    target = np.asarray(target_gps, dtype=float)
    should = np.asarray(on, dtype=bool)
    if delivered.ndim != 2 or delivered.shape != target.shape or \
            delivered.shape != should.shape or delivered.shape[0] != t.size:
        raise ValueError(f"delivered {delivered.shape}, target {target.shape} and on "
                         f"{should.shape} must all be (len(t) = {t.size}, rows)")
    if row_gain is not None:
        target = _split_by_gain(target, should, np.asarray(row_gain, dtype=float))
    if transport_s < 0:
        raise ValueError(f"transport must be >= 0 s, got {transport_s}")
    judged = t + transport_s <= t[-1]
    if judged.sum() < 2:
        raise ValueError(f"the run ({t[-1] - t[0]:.2f} s) is not longer than the transport "
                         f"({transport_s:.2f} s)")
    dt = float(np.median(np.diff(t)))
    tj = t[judged]
    # what row j laid from sample k to k+1 of the metering's time (landed transport_s later)
    landed = np.column_stack([np.interp(tj + transport_s, t, delivered[:, j])
                              for j in range(delivered.shape[1])])
    mass = np.diff(landed, axis=0)                                   # (kj-1, s)
    should_j = should[judged][:-1]
    target_j = target[judged][:-1]
    settled = _settled_off(should_j, max(0, round(settle_s / dt)))
    accuracy, laid, aimed, on_s, off_g, off_s = [], [], [], [], [], []
    for j in range(mass.shape[1]):
        row_on = should_j[:, j]
        laid_j = float(mass[row_on, j].sum())
        aimed_j = float(target_j[row_on, j].sum() * dt)
        accuracy.append(accuracy_theta(aimed_j, laid_j) if aimed_j > 0 else float("nan"))
        laid.append(laid_j)
        aimed.append(aimed_j)
        on_s.append(float(row_on.sum() * dt))
        row_off = settled[:, j]
        off_s.append(float(row_off.sum() * dt))
        off_g.append(float(mass[row_off, j].sum()) if row_off.any() else float("nan"))
    return RowsApplied(tuple(accuracy), tuple(laid), tuple(aimed), tuple(on_s), tuple(off_g),
                       tuple(off_s))


def _split_by_gain(target: np.ndarray, should: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """(k, s): each sample's total target split among the metering rows by their gains."""
    if gain.shape != (target.shape[1],) or not np.all(gain > 0):
        raise ValueError(f"row_gain must be {target.shape[1]} positive gains, got {gain}")
    total = np.where(should, target, 0.0).sum(axis=1, keepdims=True)
    weights = np.where(should, gain[None, :], 0.0)
    norm = weights.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(norm > 0, total * weights / norm, 0.0)


def _settled_off(should: np.ndarray, n: int) -> np.ndarray:
    """(k, s) True where a row should not meter and has not for the ``n`` samples before."""
    out = ~should
    for lag in range(1, n + 1):
        before = np.vstack([np.zeros((lag, should.shape[1]), bool), should[:-lag]])
        out &= ~before
    return out
