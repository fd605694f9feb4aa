"""The conformance checks as pure functions of a run's frame columns (numpy, no loop over
frames), unit-tested on their own. :mod:`hil.conformance.measure` turns them into
measurements with limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hil.conformance.declared import FrameKey
from hil.conformance.framelog import FrameLog
from hil.softbus.timing import frame_bits


def frame_keys(log: FrameLog) -> np.ndarray:
    """One int64 per frame identifying (identifier, 29-bit): bit 32 set for 29-bit ids."""
    return log.can_id + (log.extended.astype(np.int64) << 32)


def key_of(key: FrameKey) -> int:
    """:func:`frame_keys`' value of a (identifier, 29-bit) pair."""
    return key[0] + (int(key[1]) << 32)


def count_by_key(keys: np.ndarray) -> dict[int, int]:
    """How many frames of each key."""
    values, counts = np.unique(keys, return_counts=True)
    return dict(zip(values.tolist(), counts.tolist(), strict=True))


def power_ups(is_bootup: np.ndarray) -> np.ndarray:
    """Per frame (in log order), the number of boot-up frames at or before it: 0 for frames
    before the first boot-up, 1 in the first power-up, and so on."""
    return np.cumsum(is_bootup)


def series(segment: np.ndarray, time_s: np.ndarray, unheard_s: np.ndarray) -> np.ndarray:
    """Per frame (in log order), the unbroken series it belongs to: a power-up (``segment``)
    cut wherever the DUT sent frames that a fault kept from the rig (``unheard_s``, sorted:
    a cut wire). The interval across such frames is the fault's gap, not a cycle of the DUT's.

    >>> series(np.array([1, 1, 1, 1]), np.array([0.0, 0.1, 0.5, 0.6]), np.array([0.2, 0.3]))
    array([3, 3, 5, 5])
    """
    cuts = np.searchsorted(unheard_s, time_s, side="left")
    return segment * (unheard_s.size + 1) + cuts


def intervals_cut(segment: np.ndarray, series_of: np.ndarray) -> int:
    """How many intervals within a power-up a cut (:func:`series`) leaves unjudged."""
    if segment.size < 2:
        return 0
    same = segment[1:] == segment[:-1]
    return int(np.count_nonzero(same & (series_of[1:] != series_of[:-1])))


def intervals(time_s: np.ndarray, segment: np.ndarray) -> np.ndarray:
    """Intervals between successive frames of one message, within a power-up only (the gap
    across a restart is no cycle of the DUT's)."""
    if time_s.size < 2:
        return np.zeros(0)
    same = segment[1:] == segment[:-1]
    return np.diff(time_s)[same]


@dataclass(frozen=True)
class CycleStats:
    """Intervals of a cyclic message against its declared period.

    ``deviation_pct``: (median - declared) / declared in %; ``outside``: intervals off the
    declared period by more than the band; ``outside_pct``: their share in %.
    """

    count: int
    median_ms: float
    min_ms: float
    max_ms: float
    outside: int
    outside_pct: float
    deviation_pct: float


def cycle_stats(gaps_s: np.ndarray, declared_ms: float, low_pct: float, high_pct: float,
                resolution_ms: float) -> CycleStats:
    """Median, min and max of ``gaps_s`` and how many lie outside the band
    ``declared·(1 + low_pct/100) - resolution`` … ``declared·(1 + high_pct/100) + resolution``
    (``resolution``: how finely the rig's time stamps place a frame).

    >>> s = cycle_stats(np.array([0.1, 0.1, 0.1, 0.2]), 100.0, -10, 10, 0.0)
    >>> s.median_ms, s.max_ms, s.outside, s.outside_pct, s.deviation_pct
    (100.0, 200.0, 1, 25.0, 0.0)
    """
    if gaps_s.size == 0:
        nan = float("nan")
        return CycleStats(0, nan, nan, nan, 0, nan, nan)
    ms = gaps_s * 1000.0
    median = float(np.median(ms))
    lo = declared_ms * (1 + low_pct / 100.0) - resolution_ms - 1e-6
    hi = declared_ms * (1 + high_pct / 100.0) + resolution_ms + 1e-6
    outside = int(np.count_nonzero((ms < lo) | (ms > hi)))
    return CycleStats(int(ms.size), median, float(ms.min()), float(ms.max()), outside,
                      100.0 * outside / ms.size,
                      round(100.0 * (median - declared_ms) / declared_ms, 9))


def total_bits(log: FrameLog) -> int:
    """Exact bits on the wire of every frame in ``log`` (stuff bits and intermission
    included), by the software bus's own count, made once per distinct frame."""
    if len(log) == 0:
        return 0
    n = len(log)
    table = np.zeros((n, 2), dtype=np.uint64)
    # identifier, 29-bit flag and length in one word; the 8 payload bytes in the other
    table[:, 0] = (log.can_id.astype(np.uint64) | (log.extended.astype(np.uint64) << 32)
                   | (log.dlc.astype(np.uint64) << 40))
    table[:, 1] = np.ascontiguousarray(log.data).view(np.uint64)[:, 0]
    rows = np.ascontiguousarray(table).view(np.dtype((np.void, 16)))[:, 0]
    unique, first, counts = np.unique(rows, return_index=True, return_counts=True)
    del unique
    ids = log.can_id[first].tolist()
    extended = log.extended[first].tolist()
    dlcs = log.dlc[first].tolist()
    payloads = [bytes(row) for row in log.data[first].tolist()]
    total = 0
    for can_id, ext, dlc, payload, count in zip(ids, extended, dlcs, payloads,
                                                counts.tolist(), strict=True):
        total += count * frame_bits(can_id, ext, payload[:dlc])
    return total


def sync_latency(sync_s: np.ndarray, command_s: np.ndarray) -> np.ndarray:
    """For each SYNC, the time until the first command frame at or after it (s); SYNCs with no
    command after them (the end of the run) are left out.

    >>> sync_latency(np.array([0.0, 0.1, 0.2]), np.array([0.003, 0.104, 0.11])).round(3)
    array([0.003, 0.004])
    """
    if sync_s.size == 0 or command_s.size == 0:
        return np.zeros(0)
    after = np.searchsorted(command_s, sync_s, side="left")
    ok = after < command_s.size
    return command_s[after[ok]] - sync_s[ok]


def heard_sync_latency(sync_s: np.ndarray, command_s: np.ndarray,
                       unheard_s: np.ndarray) -> np.ndarray:
    """:func:`sync_latency`, leaving out the SYNCs whose first command after them was one a
    fault kept from the rig (``unheard_s``: a cut wire): the DUT answered those, nobody heard it.

    >>> heard_sync_latency(np.array([0.0, 0.1, 0.2]), np.array([0.003, 0.204]),
    ...                    np.array([0.103])).round(3)
    array([0.003, 0.004])
    """
    if unheard_s.size == 0:
        return sync_latency(sync_s, command_s)
    times = np.concatenate([command_s, unheard_s])
    heard = np.concatenate([np.ones(command_s.size, bool), np.zeros(unheard_s.size, bool)])
    order = np.argsort(times, kind="stable")
    times, heard = times[order], heard[order]
    if sync_s.size == 0 or times.size == 0:
        return np.zeros(0)
    after = np.searchsorted(times, sync_s, side="left")
    ok = after < times.size
    ok[ok] = heard[after[ok]]
    return times[after[ok]] - sync_s[ok]
