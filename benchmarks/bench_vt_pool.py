"""How long the VT takes to parse and validate a 100 kB object pool (issue 39's target: < 0.2 s).

The pool is :func:`hil.isobus.vt.samples.large_pool` (about 105 kB, 1,700 objects: masks of
numbers, strings and rectangles, soft keys, 8-bit pictures)::

    python -m pytest benchmarks/bench_vt_pool.py -s -p no:cacheprovider
"""

from __future__ import annotations

import statistics
from collections.abc import Callable
from typing import Any

from hil.isobus.vt.pool import ObjectPool
from hil.isobus.vt.samples import large_pool

TARGET_S = 0.2


def test_parse_100_kb_pool(benchmark: Any, timed_rounds: Callable[[], list[float]]) -> None:
    data = large_pool().to_bytes()
    assert len(data) >= 100_000
    pool = benchmark.pedantic(lambda: ObjectPool.from_transfers([data], 4), rounds=20,
                              iterations=1, warmup_rounds=2)
    assert pool.to_bytes() == data and pool.working_set is not None
    rounds = timed_rounds()
    median = statistics.median(rounds)
    print(f"\nVT pool of {len(data):,} bytes, {len(pool):,} objects: parse + validate "
          f"median {median * 1000:.1f} ms, max {max(rounds) * 1000:.1f} ms "
          f"(target {TARGET_S * 1000:.0f} ms)")
