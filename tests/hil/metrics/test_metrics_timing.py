"""Timing-health summary and the worst-case merge over runs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil.clock.base import TimingHealth, TimingLimits
from hil.metrics import merge_timing, timing_summary


def health(lateness_s: np.ndarray) -> TimingHealth:
    return TimingHealth.from_lateness(lateness_s, period_s=1e-3, scheduler="test",
                                      limits=TimingLimits(), miss_threshold_s=0.25e-3,
                                      stall_threshold_s=10e-3)


def run(n_late: int, worst_s: float) -> np.ndarray:
    """1000 ticks: the rest at 50 µs, ``n_late`` at 300 µs, one at ``worst_s``."""
    return np.array([50e-6] * (999 - n_late) + [300e-6] * n_late + [worst_s])


def test_single_run_summary() -> None:
    s = timing_summary(health(run(9, 20e-3)))
    assert s.runs == 1 and s.ticks == 1000 and s.modes == ("realtime",)
    assert s.lateness_p50_us == pytest.approx(50.0)
    assert s.lateness_p99_us == pytest.approx(52.5)       # 50 + 0.01 * 250 (linear percentile)
    assert s.lateness_max_us == pytest.approx(20000.0)
    assert (s.misses, s.stalls) == (10, 1)
    assert s.miss_fraction == pytest.approx(0.01)
    assert s.longest_stall_us == pytest.approx(20000.0)
    assert not s.valid and s.invalid_reasons == ("10 of 1000 ticks missed (> 0.5%)",)
    assert s.histogram_exact and s.histogram_ticks == 1000
    # a dict read back from JSON (lists for tuples) gives the same
    again = timing_summary(json.loads(json.dumps(health(run(9, 20e-3)).to_dict())))
    assert again == s


def test_merge_with_equal_edges_is_exact() -> None:
    a, b = run(2, 20e-3), run(4, 20e-3)                    # same worst: same bin edges
    m = merge_timing([health(a), health(b)], labels=["bench A", "bench B"])
    edges = np.asarray(health(a).histogram_edges_s)
    pooled, _ = np.histogram(np.concatenate([a, b]), bins=edges)
    assert m.histogram_exact
    assert m.histogram_counts == tuple(int(c) for c in pooled)
    assert (m.runs, m.ticks, m.misses, m.stalls) == (2, 2000, 3 + 5, 2)
    assert m.worst_miss_fraction == pytest.approx(0.005)
    assert m.miss_fraction == pytest.approx(0.004)
    assert m.valid                                          # 0.3 % and 0.5 %: both within
    assert m.lateness_max_us == pytest.approx(20000.0)


def test_merge_with_different_edges_is_conservative() -> None:
    a, b = run(30, 1e-3), run(3, 20e-3)
    ha, hb = health(a), health(b)
    assert ha.histogram_edges_s != hb.histogram_edges_s
    m = merge_timing([ha, hb])
    assert not m.histogram_exact and m.notes
    assert sum(m.histogram_counts) == 2000
    assert m.lateness_p99_us == pytest.approx(max(ha.lateness_p99_s, hb.lateness_p99_s) * 1e6)
    assert not m.valid and m.invalid_reasons == ("run 0: 31 of 1000 ticks missed (> 0.5%)",)
    edges_s = np.asarray(m.histogram_edges_us) * 1e-6
    counts = np.asarray(m.histogram_counts)
    pooled = np.concatenate([a, b])
    for j, x in enumerate(edges_s[:-1]):
        # ticks at or after each edge: never fewer in the merged histogram than really were
        assert counts[j:].sum() >= (pooled >= x * (1 + 1e-9)).sum()
    # and no more pessimistic than one source bin: every tick up to 1 ms stays in bins
    # ending by a's last edge (1.01 ms); only b's 20 ms stall lies beyond
    assert counts[edges_s[1:] <= 1.0101e-3].sum() == 1999


def test_lockstep_runs_merge_without_a_histogram() -> None:
    lock = TimingHealth(mode="lockstep", period_s=1e-3, ticks=5000, scheduler="virtual")
    m = merge_timing([lock, health(run(1, 2e-3))])
    assert m.modes == ("lockstep", "realtime")
    assert m.ticks == 6000 and m.histogram_ticks == 1000
    assert any("covers 1 of 2 runs" in n for n in m.notes)
    assert m.valid
    assert timing_summary(lock).histogram_counts == ()
    with pytest.raises(ValueError):
        merge_timing([])
