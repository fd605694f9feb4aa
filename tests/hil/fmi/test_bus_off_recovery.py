"""Bus off and back for an LS-BUS node FMU: ISO 11898-1's recovery (128 occurrences of 11
consecutive recessive bits, counted on the rig's bus time at its bit rate) and the software
bus's ``busoff`` rule reaching the FMU as bus off."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.fmi import lsbus
from hil.fmi.canbus import CAN_ERR_BUSOFF, CAN_ERR_CRTL, CanNodeBus
from hil.softbus import FaultKind, FaultRule, SoftwareBus
from hil.softbus.faults import FaultTable
from hil.softbus.timing import frame_bits

BITRATE = 250_000
ERROR = can.Message(arbitration_id=CAN_ERR_CRTL, is_error_frame=True, is_extended_id=True)
BUS_OFF = can.Message(arbitration_id=CAN_ERR_CRTL | CAN_ERR_BUSOFF, is_error_frame=True,
                      is_extended_id=True)
OWN = lsbus.encode([lsbus.CanTransmit(id=0x1A0, data=b"\x01\x02")])


def ops(bus: CanNodeBus) -> list[object]:
    return lsbus.decode(bus.take(), where="Rx_Data")


def statuses(operations: list[object]) -> list[int]:
    return [op.status for op in operations if isinstance(op, lsbus.Status)]


def node_at_bus_off(now_s: float = 1.0) -> CanNodeBus:
    """A node whose 32 frames in a row were destroyed: transmit errors up to bus off."""
    bus = CanNodeBus("CanChannel", True, BITRATE)
    bus.start()
    bus.time_advanced(now_s)
    seen: list[int] = []
    for _ in range(32):
        assert bus.from_node(OWN), "the node's frame goes on the bus while it is not off"
        bus.from_bus(ERROR)
        seen += statuses(ops(bus)) if bus.pending() else []
    assert bus.status == lsbus.BUS_OFF and bus.tec == 256
    assert bus.bus_off_at_s == now_s
    assert seen[-2:] == [lsbus.ERROR_PASSIVE, lsbus.BUS_OFF]
    return bus


def test_an_idle_bus_brings_the_node_back_after_128_x_11_bit_times() -> None:
    bus = node_at_bus_off(1.0)
    assert bus.from_node(OWN) == [] and bus.counts["dropped_bus_off"] == 1
    bus.time_advanced(1.0 + 127 * 11 / BITRATE)          # 127 occurrences: still off
    assert bus.status == lsbus.BUS_OFF and bus.recovery_occurrences() == 127
    assert not bus.pending()
    bus.time_advanced(1.0 + 128 * 11 / BITRATE)          # the 128th: error active again
    assert bus.status == lsbus.ERROR_ACTIVE and bus.tec == 0 and bus.rec == 0
    assert statuses(ops(bus)) == [lsbus.ERROR_ACTIVE]
    assert bus.recovered_at_s == pytest.approx(1.0 + 1408 / BITRATE)
    [frame] = bus.from_node(OWN)                         # its frames go on the bus again
    assert frame.arbitration_id == 0x1A0
    assert bus.record()["bus_off_recoveries"] == 1 and bus.record()["bus_off"] == 1


def test_a_busy_bus_counts_one_occurrence_per_frame() -> None:
    """Back-to-back frames leave no idle time: only each frame's end of 11 recessive bits
    counts, so 128 frames are needed, however many bit times pass."""
    bus = node_at_bus_off(0.0)
    frame = can.Message(arbitration_id=0x18FF0010, is_extended_id=True, data=bytes(8))
    bits = frame_bits(frame.arbitration_id, True, bytes(frame.data))
    for n in range(1, 129):
        bus.from_bus(frame)
        bus.time_advanced(n * bits / BITRATE)
        if n < 128:
            assert bus.status == lsbus.BUS_OFF, n
    assert bus.status == lsbus.ERROR_ACTIVE
    assert bus.counts["missed_bus_off"] == 128       # it heard none of them while off


def test_a_bus_off_error_frame_takes_its_sender_off_at_once_and_not_the_others() -> None:
    sender = CanNodeBus("CanChannel", True, BITRATE)
    sender.start()
    ops(sender)
    sender.from_node(OWN)
    sender.from_bus(BUS_OFF)
    got = ops(sender)
    assert [op.is_sender for op in got if isinstance(op, lsbus.BusError)] == [True]
    assert statuses(got) == [lsbus.BUS_OFF] and sender.tec == 256
    listener = CanNodeBus("CanChannel", True, BITRATE)   # no frame of its own on the bus
    listener.start()
    listener.from_bus(BUS_OFF)
    assert listener.status == lsbus.ERROR_ACTIVE and listener.rec == 1 and listener.tec == 0


def test_the_software_bus_busoff_rule_sends_a_bus_off_error_frame() -> None:
    table = FaultTable()
    table.add(FaultRule(FaultKind.BUSOFF, can_id=0x1A0, mask=0x7FF))
    first = table.apply(0x1A0, b"")
    assert first.error_frame and first.bus_off
    error = FaultTable()
    error.add(FaultRule(FaultKind.ERROR, can_id=0x1A0, mask=0x7FF))
    assert not error.apply(0x1A0, b"").bus_off
    with SoftwareBus(port=0) as sb:
        node, rig = open_bus(sb.spec()), open_bus(sb.spec())
        try:
            sb.add_fault(FaultRule(FaultKind.BUSOFF, can_id=0x1A0, mask=0x7FF))
            node.send(can.Message(arbitration_id=0x1A0, data=b"\x01", is_extended_id=False))
            msg = rig.recv(2.0)
            assert msg is not None and msg.is_error_frame
            assert msg.arbitration_id == CAN_ERR_CRTL | CAN_ERR_BUSOFF
        finally:
            node.shutdown()
            rig.shutdown()


def test_the_probe_fmu_hears_bus_off_and_error_active_again(fmus: Path) -> None:
    """In lockstep: the busoff rule's error frame after the probe's report takes it bus off;
    at the next SYNC (0.1 s later: 25,000 bit times) it is error active again and reports."""
    from tests.hil.fmi.test_bus_fmu import SYNC, controller, report

    c = controller(fmus)
    try:
        c.on_start()
        assert report(c.on_frame(SYNC))["status"] == lsbus.ERROR_ACTIVE
        assert c.on_frame(BUS_OFF) == []          # its report was destroyed: it is off
        assert c.bus.status == lsbus.BUS_OFF and c.record()["bus_off"] == 1
        back = report(c.on_frame(SYNC))           # recovered with the next SYNC
        assert back["status"] == lsbus.ERROR_ACTIVE and back["as_sender"] == 1
        record = c.record()
        assert record["bus_off_recoveries"] == 1 and record["recovered_at_s"] == 0.1
        assert record["delivered"]["status"] == 3     # active, bus off, active again
    finally:
        c.close()


@pytest.mark.slow
def test_the_busoff_rule_on_the_software_bus_takes_the_fmu_off_and_it_recovers(
        fmus: Path) -> None:
    """The probe on the software bus (its own thread), the ``busoff`` rule on its report: its
    first report's error frame takes it bus off; the next SYNC brings it back, and the rule,
    holding, drops its later reports without a word (they are confirmed: see the guide)."""
    import time

    from hil.dut.fmu import FmuDut
    from tests.hil.fmi.test_bus_fmu import REPORT, SYNC, controller

    c = controller(fmus)
    with SoftwareBus(port=0) as sb:
        dut = FmuDut(c, lambda: controller(fmus), fmu_file=c.fmu.path, level="bus")
        rig = open_bus(sb.spec())
        try:
            dut.start(sb.spec())
            sb.add_fault(FaultRule(FaultKind.BUSOFF, can_id=REPORT, mask=0x7FF))
            for _ in range(5):
                rig.send(SYNC)
                time.sleep(0.1)
            dut.check()
            record = dut.controller.record()   # type: ignore[attr-defined]
            assert record["bus_off"] == 1 and record["bus_errors"] == 1
            assert record["bus_off_recoveries"] == 1 and record["status"] == "error active"
            reports = [m for m in iter(lambda: rig.recv(0.05), None)
                       if not m.is_error_frame and m.arbitration_id == REPORT]
            assert reports == []                          # the rule holds them all off
        finally:
            rig.shutdown()
            dut.stop()
