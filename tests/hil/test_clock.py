from __future__ import annotations

import gc
import threading

import can
import numpy as np
import pytest

from hil.bus import open_bus
from hil.clock import (
    STEP_END_ID,
    LockstepClock,
    RealtimeClock,
    StepOrderError,
    SyncBarrier,
    TimingLimits,
    make_clock,
)
from hil.clock.base import TimingHealth
from hil.errors import ClockError, ConfigError, StepTimeoutError


def test_lockstep_is_virtual_and_batches() -> None:
    clock = LockstepClock(0.001)
    clock.start()
    assert clock.tick(250) == 250
    assert clock.time_s == pytest.approx(0.25)
    assert clock.health().mode == "lockstep"


def test_clock_misuse_is_an_error() -> None:
    clock = RealtimeClock(0.001)
    with pytest.raises(ClockError, match="before start"):
        clock.tick()
    clock.start()
    with pytest.raises(ClockError, match="one tick at a time"):
        clock.tick(2)
    with pytest.raises(ClockError, match="started twice"):
        clock.start()
    clock.stop()
    with pytest.raises(ClockError):
        LockstepClock(0)
    with pytest.raises(ConfigError, match="unknown clock"):
        make_clock("sundial")


@pytest.mark.realtime
def test_realtime_clock_keeps_absolute_deadlines_and_reports_health() -> None:
    clock = RealtimeClock(0.001)
    clock.start()
    for _ in range(300):
        clock.tick()
    elapsed = clock.elapsed_s
    health = clock.stop()
    assert health.ticks == 300
    assert elapsed >= 0.3  # never early: the 300th deadline is 0.3 s after start
    assert health.lateness_p50_s >= 0.0 and health.lateness_max_s >= health.lateness_p99_s
    assert health.scheduler.startswith(("SCHED_FIFO", "SCHED_OTHER"))
    assert sum(health.histogram_counts) == 300
    print(f"\n1 kHz: p50 {health.lateness_p50_s * 1e6:.0f} us, p99 "
          f"{health.lateness_p99_s * 1e6:.0f} us, max {health.lateness_max_s * 1e6:.0f} us, "
          f"{health.scheduler}")


def test_realtime_runs_freeze_the_heap_until_the_last_one_stops() -> None:
    """A full collection in mid-run walked every object the imports left (46-50 ms on the
    depth rig): a run freezes them, and overlapping runs unfreeze only when the last stops."""
    base = gc.get_freeze_count()
    assert base == 0, "another test left the heap frozen"
    first, second = RealtimeClock(0.001), RealtimeClock(0.001)
    first.start()
    frozen = gc.get_freeze_count()
    assert frozen > 0
    second.start()
    first.stop()
    assert gc.get_freeze_count() >= frozen          # the second run is still going
    second.stop()
    assert gc.get_freeze_count() == 0
    first.stop()                                     # a second stop changes nothing
    assert gc.get_freeze_count() == 0


def test_health_judges_the_bench_not_the_dut() -> None:
    quiet = np.full(1000, 20e-6)
    ok = TimingHealth.from_lateness(quiet, period_s=1e-3, scheduler="x", limits=TimingLimits(),
                                    miss_threshold_s=5e-4, stall_threshold_s=2e-3)
    assert ok.valid and ok.misses == 0 and ok.lateness_p99_s == pytest.approx(20e-6)
    noisy = quiet.copy()
    noisy[::50] = 1e-3   # 2 % misses
    noisy[501] = 0.2     # one 200 ms stall
    bad = TimingHealth.from_lateness(noisy, period_s=1e-3, scheduler="x",
                                     limits=TimingLimits(), miss_threshold_s=5e-4,
                                     stall_threshold_s=2e-3)
    assert not bad.valid
    assert bad.misses == 21 and bad.stalls == 1 and bad.longest_stall_s == pytest.approx(0.2)
    assert any("missed" in r for r in bad.invalid_reasons)
    assert any("stall" in r for r in bad.invalid_reasons)


def _dut(bus: can.BusABC, stop: threading.Event, answer_ids: list[int]) -> None:
    while not stop.is_set():
        msg = bus.recv(0.05)
        if msg is not None and msg.arbitration_id == 0x080:
            for can_id in answer_ids:
                bus.send(can.Message(arbitration_id=can_id, data=b"\x01", is_extended_id=False))


def test_sync_barrier_waits_for_the_dut_in_lockstep() -> None:
    rig_bus, dut_bus = open_bus("virtual:barrier1"), open_bus("virtual:barrier1")
    stop = threading.Event()
    dut = threading.Thread(target=_dut, args=(dut_bus, stop, [0x201, 0x701]))
    dut.start()
    received: list[int] = []
    try:
        clock = LockstepClock(0.001)
        barrier = SyncBarrier(rig_bus, period_ticks=10, await_ids=[0x201],
                              dispatch=lambda m: received.append(m.arbitration_id))
        clock.add_participant(barrier)
        clock.start()
        for _ in range(5):
            clock.tick(10)
            clock.complete_step()
        assert barrier.syncs_sent == 5
        assert received.count(0x201) == 5
    finally:
        stop.set()
        dut.join()
        rig_bus.shutdown()
        dut_bus.shutdown()


def test_silent_dut_fails_the_step_clearly() -> None:
    rig_bus = open_bus("virtual:barrier2")
    try:
        clock = LockstepClock(0.001)
        clock.add_participant(SyncBarrier(rig_bus, period_ticks=100, await_ids=[0x201, 0x202],
                                          dispatch=lambda m: None, timeout_s=0.2))
        clock.start()
        clock.tick(100)
        with pytest.raises(StepTimeoutError, match=r"t=0\.100 s.*missing frames 0x201, 0x202"):
            clock.complete_step()
    finally:
        rig_bus.shutdown()


def test_realtime_barrier_only_sends_sync() -> None:
    rig_bus, listener = open_bus("virtual:barrier3"), open_bus("virtual:barrier3")
    try:
        barrier = SyncBarrier(rig_bus, period_ticks=1, await_ids=[0x201],
                              dispatch=lambda m: None, timeout_s=0.01, with_counter=True)
        barrier.complete(1, 0.001, wait=False)   # no DUT, no wait, no error
        sync = listener.recv(1.0)
        assert sync is not None and sync.arbitration_id == 0x080 and bytes(sync.data) == b"\x01"
    finally:
        rig_bus.shutdown()
        listener.shutdown()


# --- where a step ends: the command frame, or the DUT's step-end frame ------------------------

class _ScriptedDut(can.BusABC):
    """The rig's bus to a DUT that answers SYNC ``n`` with ``answers[n]`` (queued at once)."""

    def __init__(self, boot: list[int], answers: list[list[int]]) -> None:
        self._rx = [_frame(i) for i in boot]
        self._answers = answers
        self._syncs = 0
        super().__init__(channel="scripted")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        assert msg.arbitration_id == 0x080
        self._rx += [_frame(i) for i in self._answers[self._syncs]]
        self._syncs += 1

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return (self._rx.pop(0) if self._rx else None), False


def _frame(can_id: int) -> can.Message:
    if can_id == STEP_END_ID:
        return can.Message(arbitration_id=STEP_END_ID, is_extended_id=True, data=b"")
    return can.Message(arbitration_id=can_id, is_extended_id=False, data=b"\x05")


END = STEP_END_ID


def _steps(bus: _ScriptedDut, n: int) -> tuple[SyncBarrier, list[list[int]]]:
    """``n`` lockstep steps; each step's dispatched ids, then what was left on the bus."""
    steps: list[list[int]] = []
    barrier = SyncBarrier(bus, period_ticks=1, await_ids=[0x220], timeout_s=0.05,
                          dispatch=lambda m: steps[-1].append(m.arbitration_id))
    for k in range(n):
        steps.append([])
        barrier.complete(k, k * 0.1, wait=True)
        while (msg := bus.recv(0.0)) is not None:
            error = barrier.late_frame_error(msg, k * 0.1)
            if error is not None:
                raise error
    return barrier, steps


def test_a_dut_that_marks_its_steps_may_send_its_command_first() -> None:
    bus = _ScriptedDut([0x710, END], [[0x220, 0x1A0, 0x710, END]] * 3)
    barrier, steps = _steps(bus, 3)
    assert barrier.marks_steps and barrier.step_ends == 4
    assert steps == [[0x710, 0x220, 0x1A0, 0x710], [0x220, 0x1A0, 0x710],
                     [0x220, 0x1A0, 0x710]]


def test_without_step_end_frames_the_command_ends_the_step() -> None:
    bus = _ScriptedDut([0x710], [[0x1A0, 0x710, 0x220]] * 2)
    barrier, steps = _steps(bus, 2)
    assert not barrier.marks_steps and barrier.step_ends == 0
    assert steps == [[0x710, 0x1A0, 0x710, 0x220], [0x1A0, 0x710, 0x220]]


def test_a_frame_after_the_command_names_the_cause_and_the_fix() -> None:
    bus = _ScriptedDut([0x710], [[0x220, 0x710]])
    with pytest.raises(StepOrderError) as err:
        _steps(bus, 1)
    text = str(err.value)
    assert "t=0.000 s" in text and "frame 0x710 after its command frame 0x220" in text
    assert "send the command frame last" in text
    assert "step-end frame (extended id 0x1FFFFFF0, no data)" in text and "after boot-up" in text
    assert "docs/guide/clocks.md" in text


@pytest.mark.parametrize(("boot", "answers", "match"), [
    # the first step-end frame after the first command: too late to count as an announcement
    ([0x710], [[0x220, END]], "first step-end frame 0x1FFFFFF0 came after its first command"),
    # announced, then a step ended before its command frame
    ([0x710, END], [[0x220, END], [END, 0x220]],
     r"ended its step \(step-end frame 0x1FFFFFF0\) before its command frame 0x220"),
    # announced, then a frame after the step-end frame
    ([0x710, END], [[0x220, END, 0x710]], "sent frame 0x710 after its step-end frame"),
    # announced, then two step-end frames in a step
    ([0x710, END], [[0x220, END, END]], "second step-end frame"),
])
def test_a_misplaced_step_end_frame_is_named(boot: list[int], answers: list[list[int]],
                                             match: str) -> None:
    with pytest.raises(StepOrderError, match=match):
        _steps(_ScriptedDut(boot, answers * 2), 2)


def test_a_dut_that_announced_but_never_ends_its_step_times_out_naming_the_frame() -> None:
    with pytest.raises(StepTimeoutError, match="its step-end frame 0x1FFFFFF0 did not"):
        _steps(_ScriptedDut([0x710, END], [[0x220]]), 1)


def test_a_restarted_dut_announces_afresh() -> None:
    bus = _ScriptedDut([0x710, END], [[0x220, END], [0x710, 0x220]])
    barrier, _ = _steps(bus, 1)
    barrier.dut_restarted()     # the new DUT does not mark its steps: its command ends them
    barrier.complete(1, 0.1, wait=True)
    assert not barrier.marks_steps


def test_frames_after_the_command_are_in_order_on_a_synchronous_bus() -> None:
    """The inline bus queues a controller's whole answer within ``send``: nothing is late."""
    from hil.bus.inline import InlineBus

    bus = InlineBus(lambda msg: [_frame(0x220), _frame(0x710)] if msg.arbitration_id == 0x080
                    else [])
    barrier = SyncBarrier(bus, period_ticks=1, await_ids=[0x220], dispatch=lambda m: None)
    barrier.complete(0, 0.0, wait=True)
    msg = bus.recv(0.0)
    assert msg is not None and barrier.late_frame_error(msg, 0.0) is None


def test_the_firmware_hal_names_the_same_step_end_frame() -> None:
    from pathlib import Path

    header = (Path(__file__).resolve().parents[2] / "firmware" / "hal" / "hal_can.h").read_text()
    assert f"#define HAL_CAN_STEP_END_ID 0x{STEP_END_ID:X}u" in header
