"""Bus-level FMUs (FMI 3.0 + LS-BUS CAN) driven by agrihil as the importer.

The probe FMUs (firmware/fmu/lsbus_probe) report in a frame what the bus told them:
confirms, arbitration lost, bus errors (as sender), status, frames received, SYNCs seen.
"""

from __future__ import annotations

import time
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.dut.base import DutStopped
from hil.dut.fmu import FmuDut
from hil.fmi import lsbus
from hil.fmi.bus_node import BusFmuController
from hil.fmi.canbus import LsBusError
from hil.fmi.fmufile import open_fmu
from hil.softbus import FaultKind, FaultRule, SoftwareBus

SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
REPORT = 0x1A0


def controller(fmus: Path, name: str = "agrihil-lsbus-probe", *, notifications: bool = True,
               **params: int) -> BusFmuController:
    fmu = open_fmu(fmus / f"{name}.fmu")
    return BusFmuController(fmu, fmu.can_terminals[0], period_s=0.1,
                            bus_notifications=notifications, parameters=params)


def report(frames: list[can.Message]) -> dict[str, int]:
    [msg] = [m for m in frames if m.arbitration_id == REPORT]
    d = bytes(msg.data)
    return {"confirms": d[0], "arbitration_lost": d[1], "bus_errors": d[2], "as_sender": d[3],
            "status": d[4], "frames_in": d[5], "syncs": d[7]}


@pytest.mark.parametrize("notifications", [True, False])
def test_frames_reach_rx_data_and_confirms_follow_bus_notifications(
        fmus: Path, notifications: bool) -> None:
    c = controller(fmus, notifications=notifications)
    try:
        assert c.on_start() == []
        seen = []
        for _ in range(4):
            seen.append(report(c.on_frame(SYNC)))
            c.on_frame(can.Message(arbitration_id=0x181, data=b"\x01\x02", is_extended_id=False))
        # every frame reached it (the SYNC and the 0x181 before it); its own frames were
        # confirmed at the next SYNC (the bus time moving on), only when it asked for them
        assert [r["frames_in"] for r in seen] == [1, 3, 5, 7]
        assert [r["syncs"] for r in seen] == [1, 2, 3, 4]
        assert [r["confirms"] for r in seen] == ([0, 1, 2, 3] if notifications else [0] * 4)
        # the status at start (error active) reaches it either way
        assert {r["status"] for r in seen} == {lsbus.ERROR_ACTIVE}
        # the last report waits for a SYNC to come
        assert c.record()["confirmed"] == 3 and c.record()["bus_notifications"] is notifications
    finally:
        c.close()


def test_a_can_fd_frame_is_refused_naming_it(fmus: Path) -> None:
    c = controller(fmus, fd_at_step=2)
    try:
        c.on_start()
        c.on_frame(SYNC)
        with pytest.raises(LsBusError, match=r"CAN FD transmit of id 0x1A1 \(12 bytes\)"):
            c.on_frame(SYNC)
    finally:
        c.close()


def test_configuration_operations_reach_the_bus(fmus: Path) -> None:
    c = controller(fmus, baudrate=250_000, arbitration=lsbus.DISCARD_AND_NOTIFY)
    try:
        c.on_start()
        c.on_frame(SYNC)
        record = c.record()
        assert record["configured_baudrate"] == 250_000
        assert record["arbitration_lost_behavior"] == "discard and notify"
    finally:
        c.close()


def test_a_time_based_tx_clock_ticks_at_its_interval_and_contends_with_sync(fmus: Path) -> None:
    c = controller(fmus, "agrihil-lsbus-probe-timed")
    try:
        c.on_start()
        assert c.terminal.tx_clock_kind == "constant" and c.terminal.tx_clock_interval == 0.3
        reports = {}
        for k in range(13):
            out = c.on_frame(SYNC)
            if out:
                reports[k] = report(out)
        # ticks at 0.3, 0.6, 0.9, 1.2 s: the SYNCs 3, 6, 9, 12 (0.1 s apart, the first at 0)
        assert sorted(reports) == [3, 6, 9, 12]
        # each tick's frame (0x1A0) became ready with the SYNC (0x080) and lost arbitration to
        # it; the node hears of it with the next frame
        assert [r["arbitration_lost"] for r in reports.values()] == [0, 1, 2, 3]
        assert c.record()["arbitration_lost"] == 4
    finally:
        c.close()


def test_discard_and_notify_drops_the_frame_that_lost(fmus: Path) -> None:
    c = controller(fmus, "agrihil-lsbus-probe-timed", arbitration=lsbus.DISCARD_AND_NOTIFY)
    try:
        c.on_start()
        assert not any(c.on_frame(SYNC) for _ in range(13))
        assert c.record()["discarded"] == 4
    finally:
        c.close()


def test_software_bus_faults_reach_the_fmu_as_bus_errors_up_to_bus_off(fmus: Path) -> None:
    """The software bus's ``error`` rule destroys the probe's frames: bus errors with
    ``isSender``, error passive after 16, bus off after 32 (it then sends and hears nothing
    until its recovery, 128 x 11 recessive bits later: the next SYNC)."""
    c = controller(fmus)
    with SoftwareBus(port=0) as sb:
        dut = FmuDut(c, lambda: controller(fmus), fmu_file=c.fmu.path, level="bus")
        rig = open_bus(sb.spec())
        try:
            dut.start(sb.spec())
            rule = sb.add_fault(FaultRule(FaultKind.ERROR, can_id=REPORT, mask=0x7FF, count=20))
            got: list[can.Message] = []

            def sync_and_read() -> None:
                rig.send(SYNC)
                deadline = time.monotonic() + 0.3
                while time.monotonic() < deadline:
                    msg = rig.recv(0.05)
                    if msg is not None and not msg.is_error_frame:
                        got.append(msg)
                        return

            for _ in range(20):          # 20 reports destroyed: TEC 160, error passive
                rig.send(SYNC)
                time.sleep(0.04)
            sb.clear_faults(rule)
            sync_and_read()
            first = report(got)
            # every destroyed frame reached the FMU as a bus error; one whose error frame comes
            # after the next SYNC (a loaded host) counts as a receive error, not its own
            assert first["bus_errors"] == 20 and first["as_sender"] >= 17
            assert first["status"] == lsbus.ERROR_PASSIVE
            sb.add_fault(FaultRule(FaultKind.ERROR, can_id=REPORT, mask=0x7FF))
            for _ in range(20):          # 32 destroyed in all: TEC past 255, bus off
                rig.send(SYNC)
                time.sleep(0.04)
            dut.check()
            record = dut.controller.record()   # type: ignore[attr-defined]
            assert record["bus_off"] >= 1           # TEC past 255: bus off
            assert record["bus_off_recoveries"] >= 1  # ... back at the next SYNC, to fail again
            sb.clear_faults()
            got.clear()
            sync_and_read()
            assert got and report(got)["status"] != lsbus.BUS_OFF   # on the bus again
        finally:
            rig.shutdown()
            result = dut.stop()
    assert result["lsbus"]["bus_off"] >= 1 and result["fmu_level"] == "bus"


def test_an_fmu_error_stops_the_dut_naming_the_call(fmus: Path) -> None:
    c = controller(fmus, fd_at_step=1)
    dut = FmuDut(c, None, fmu_file=c.fmu.path, level="bus")
    bus = dut.attach_inline()
    with pytest.raises(DutStopped, match="CAN FD transmit"):
        bus.send(SYNC)
    dut.stop()
