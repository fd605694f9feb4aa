"""Real-time clock lateness at 1 kHz (sleep to deadline, then spin; SCHED_FIFO if permitted)."""

from __future__ import annotations

from hil.clock import RealtimeClock


def test_realtime_lateness_1khz(benchmark) -> None:
    results = {}

    def run() -> None:
        clock = RealtimeClock(0.001)
        clock.start()
        for _ in range(5000):
            clock.tick()
        results["health"] = clock.stop()

    benchmark.pedantic(run, rounds=1, iterations=1)
    h = results["health"]
    benchmark.extra_info.update(p50_us=h.lateness_p50_s * 1e6, p99_us=h.lateness_p99_s * 1e6,
                                p999_us=h.lateness_p999_s * 1e6, max_us=h.lateness_max_s * 1e6,
                                misses=h.misses, scheduler=h.scheduler)
    print(f"\n1 kHz real-time clock over 5 s: lateness p50 {h.lateness_p50_s * 1e6:.1f} us, "
          f"p99 {h.lateness_p99_s * 1e6:.1f} us, p99.9 {h.lateness_p999_s * 1e6:.1f} us, "
          f"max {h.lateness_max_s * 1e6:.0f} us, misses {h.misses}, {h.scheduler} "
          f"(target p99 <= 50 us)")
