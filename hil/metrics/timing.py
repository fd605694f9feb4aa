"""The rig's timing health, summarised for reports and merged over runs for qualification.

Input is a ``TimingHealth``-like record: :class:`hil.clock.base.TimingHealth` itself, its
``to_dict()``, or that dict read back from JSON (lists for tuples). Lateness is how long after
its deadline a tick started; a *miss* is a tick later than the miss threshold, a *stall* one
later than the stall threshold (hil/clock/base.py). Summaries are in microseconds.

**Merging** (:func:`merge_timing`) is worst-case, for the qualification record:

* lateness p50 / p99 / p99.9 / max: the **largest** over the runs (the worst run's figure; a
  percentile of the pooled ticks would be at most that, and could hide one bad run);
* ticks, misses, stalls: summed; ``miss_fraction`` = total misses / total ticks, and
  ``worst_miss_fraction`` the largest of any run; ``longest_stall_us`` the largest;
* ``valid`` only if every run was valid; each run's reasons are kept, prefixed by its label;
* histogram: when all runs' bin edges agree, counts are summed (exact). When they differ
  (``TimingHealth.from_lateness`` sizes the last bins from each run's worst lateness, so real
  runs usually differ) the counts are re-binned onto the union of all edges, each source bin's
  count going to the union bin that ends at the source bin's upper edge: never earlier than
  the ticks really were, so "ticks later than x" read from the merged histogram is an upper
  bound for every edge x (``histogram_exact = False``). Runs without a histogram (lockstep)
  add ticks but no counts; ``histogram_ticks`` says how many ticks the histogram holds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.metrics._common import DictMixin

__all__ = ["TimingSummary", "merge_timing", "timing_summary"]

_US = 1e6


@dataclass(frozen=True)
class TimingSummary(DictMixin):
    """Timing health of one run or (merged) the worst case of several."""

    runs: int
    modes: tuple[str, ...]
    ticks: int
    lateness_p50_us: float
    lateness_p99_us: float
    lateness_p999_us: float
    lateness_max_us: float
    misses: int
    stalls: int
    miss_fraction: float
    worst_miss_fraction: float
    longest_stall_us: float
    valid: bool
    invalid_reasons: tuple[str, ...]
    histogram_edges_us: tuple[float, ...]
    histogram_counts: tuple[int, ...]
    histogram_exact: bool
    histogram_ticks: int
    notes: tuple[str, ...] = ()


def _as_mapping(health: Mapping[str, Any] | Any) -> Mapping[str, Any]:
    if isinstance(health, Mapping):
        return health
    if hasattr(health, "to_dict"):
        return health.to_dict()
    raise TypeError(f"expected a TimingHealth or its dict, got {type(health).__name__}")


def timing_summary(health: Mapping[str, Any] | Any) -> TimingSummary:
    """Summary (µs) of one run's ``TimingHealth`` (object or dict)."""
    return merge_timing([health])


def _rebin(edges: np.ndarray, counts: np.ndarray, union: np.ndarray) -> np.ndarray:
    """Counts of bins ``edges`` moved onto ``union`` (a superset of ``edges``).

    Each goes into the union bin ending at the source bin's upper edge (conservative: never
    earlier).
    """
    out = np.zeros(union.size - 1, dtype=np.int64)
    upper = np.searchsorted(union, edges[1:])          # exact: edges are members of union
    np.add.at(out, upper - 1, counts)
    return out


def merge_timing(healths: Sequence[Mapping[str, Any] | Any], *,
                 labels: Sequence[str] | None = None) -> TimingSummary:
    """Worst-case merge of several runs' timing health (see the module docstring).

    Parameters
    ----------
    healths : sequence
        Each run's ``TimingHealth`` (object or dict).
    labels : sequence of str, optional
        The runs' names in the reasons of invalid timing (default ``run 0``, ``run 1``, ...).

    Returns
    -------
    TimingSummary
        The worst case over the runs, in µs.

    Raises
    ------
    ValueError
        No runs, or not one label per run.
    """
    records = [_as_mapping(h) for h in healths]
    if not records:
        raise ValueError("no timing health to summarise")
    if labels is None:
        labels = [f"run {i}" for i in range(len(records))]
    if len(labels) != len(records):
        raise ValueError(f"{len(labels)} labels for {len(records)} runs")
    single = len(records) == 1

    def worst(key: str) -> float:
        return max(float(r.get(key, 0.0)) for r in records) * _US

    ticks = [int(r.get("ticks", 0)) for r in records]
    misses = [int(r.get("misses", 0)) for r in records]
    total_ticks = sum(ticks)
    fractions = [m / n if n else 0.0 for m, n in zip(misses, ticks, strict=True)]
    reasons: list[str] = []
    for label, r in zip(labels, records, strict=True):
        for reason in r.get("invalid_reasons", ()):
            reasons.append(reason if single else f"{label}: {reason}")
    notes: list[str] = []

    hist = [(np.asarray(r.get("histogram_edges_s", ()), dtype=float),
             np.asarray(r.get("histogram_counts", ()), dtype=np.int64), n)
            for r, n in zip(records, ticks, strict=True)]
    hist = [(e, c, n) for e, c, n in hist if e.size >= 2 and c.size == e.size - 1]
    exact = True
    if not hist:
        edges_s, counts = np.zeros(0), np.zeros(0, dtype=np.int64)
    elif all(np.array_equal(e, hist[0][0]) for e, _, _ in hist):
        edges_s, counts = hist[0][0], sum(c for _, c, _ in hist)
    else:
        exact = False
        edges_s = np.unique(np.concatenate([e for e, _, _ in hist]))
        counts = sum(_rebin(e, c, edges_s) for e, c, _ in hist)
        notes.append("histogram bin edges differ between runs: counts re-binned onto the union "
                     "of edges, each at its bin's upper edge (an upper bound on lateness)")
    histogram_ticks = int(np.sum(counts))
    if len(hist) < len(records):
        notes.append(f"histogram covers {len(hist)} of {len(records)} runs "
                     f"({histogram_ticks} of {total_ticks} ticks)")

    return TimingSummary(
        runs=len(records), modes=tuple(sorted({str(r.get("mode", "?")) for r in records})),
        ticks=total_ticks, lateness_p50_us=worst("lateness_p50_s"),
        lateness_p99_us=worst("lateness_p99_s"), lateness_p999_us=worst("lateness_p999_s"),
        lateness_max_us=worst("lateness_max_s"), misses=sum(misses),
        stalls=sum(int(r.get("stalls", 0)) for r in records),
        miss_fraction=sum(misses) / total_ticks if total_ticks else 0.0,
        worst_miss_fraction=max(fractions), longest_stall_us=worst("longest_stall_s"),
        valid=all(bool(r.get("valid", False)) for r in records),
        invalid_reasons=tuple(reasons),
        histogram_edges_us=tuple(float(e) * _US for e in edges_s),
        histogram_counts=tuple(int(c) for c in counts), histogram_exact=exact,
        histogram_ticks=histogram_ticks, notes=tuple(notes))
