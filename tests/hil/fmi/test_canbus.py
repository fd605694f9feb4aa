"""The bus simulation one CAN node FMU sees (hil.fmi.canbus), without an FMU."""

from __future__ import annotations

import can
import pytest

from hil.fmi import lsbus
from hil.fmi.canbus import CanNodeBus, LsBusError


def frame(can_id: int, data: bytes = b"\x01", *, extended: bool = False) -> can.Message:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=extended)


ERROR_FRAME = can.Message(is_error_frame=True, arbitration_id=0x20000004, is_extended_id=True)


def ops(bus: CanNodeBus) -> list[lsbus.Operation]:
    return lsbus.decode(bus.take())


SYNC = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)


def test_transmit_goes_on_the_bus_and_is_confirmed_when_the_bus_time_moves_on() -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    bus.start()
    assert ops(bus) == [lsbus.Status(lsbus.ERROR_ACTIVE)]
    [msg] = bus.from_node(lsbus.encode([lsbus.CanTransmit(0x1A0, b"\x01\x02")]))
    assert (msg.arbitration_id, bytes(msg.data), msg.is_extended_id) == (0x1A0, b"\x01\x02", False)
    assert not bus.pending()
    bus.from_bus(frame(0x181, b"\xAA"))      # heard right after: may have been on the wire first
    assert ops(bus) == [lsbus.CanTransmit(0x181, b"\xAA")]
    bus.time_advanced()
    bus.from_bus(SYNC)
    assert ops(bus) == [lsbus.Confirm(0x1A0), lsbus.CanTransmit(0x080, b"")]


def test_without_notifications_nothing_but_frames_comes_back() -> None:
    bus = CanNodeBus("CanChannel", notifications=False)
    bus.from_node(lsbus.encode([lsbus.CanTransmit(0x300, b"")]))
    bus.from_bus(ERROR_FRAME)
    bus.time_advanced()
    bus.from_bus(SYNC)
    assert ops(bus) == [lsbus.CanTransmit(0x080, b"")]
    assert bus.counts["bus_errors"] == 1 and bus.counts["confirmed"] == 0


@pytest.mark.parametrize("op, kind", [
    (lsbus.CanFdTransmit(0x123, b"x" * 12), "CAN FD"),
    (lsbus.CanXlTransmit(0x123, b"x" * 100), "CAN XL"),
])
def test_fd_and_xl_are_refused_on_the_classic_bus(op: lsbus.Operation, kind: str) -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    with pytest.raises(LsBusError, match=f"{kind} transmit of id 0x123.*classic CAN bus"):
        bus.from_node(lsbus.encode([op]))


@pytest.mark.parametrize("op", [lsbus.Confirm(1), lsbus.ArbitrationLost(1),
                                lsbus.BusError(1, 1), lsbus.Status(1)])
def test_operations_of_the_bus_are_refused_from_a_node(op: lsbus.Operation) -> None:
    with pytest.raises(LsBusError, match="not one a CAN node sends"):
        CanNodeBus("CanChannel", notifications=True).from_node(lsbus.encode([op]))


def test_a_format_error_from_the_node_is_an_error() -> None:
    with pytest.raises(LsBusError, match="format error"):
        CanNodeBus("T", notifications=True).from_node(lsbus.encode([lsbus.FormatError(b"zz")]))


def test_arbitration_against_a_rig_frame_of_the_same_instant() -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    # 0x1A0 loses to 0x080 (lower id wins), 0x001 wins; buffered and sent after by default
    out = bus.from_node(lsbus.encode([lsbus.CanTransmit(0x1A0, b""),
                                      lsbus.CanTransmit(0x001, b"")]), contending=frame(0x080))
    assert [m.arbitration_id for m in out] == [0x1A0, 0x001]
    assert ops(bus) == [lsbus.ArbitrationLost(0x1A0)]
    # a standard id beats an extended one of the same base id
    assert bus.from_node(lsbus.encode([lsbus.CanTransmit(0x080 << 18, b"", ide=True)]),
                         contending=frame(0x080))
    assert ops(bus) == [lsbus.ArbitrationLost(0x080 << 18)]


def test_discard_and_notify_drops_the_losing_frame() -> None:
    bus = CanNodeBus("CanChannel", notifications=False)
    config = lsbus.Configuration(lsbus.ARBITRATION_LOST_BEHAVIOR, lsbus.DISCARD_AND_NOTIFY)
    out = bus.from_node(lsbus.encode([config, lsbus.CanTransmit(0x1A0, b""),
                                      lsbus.CanTransmit(0x010, b"")]), contending=frame(0x080))
    assert [m.arbitration_id for m in out] == [0x010]
    assert bus.counts["discarded"] == 1 and not bus.pending()   # no notifications


def test_configuration_is_kept() -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    bus.from_node(lsbus.encode([lsbus.Configuration(lsbus.CAN_BAUDRATE, 250_000)]))
    assert bus.record()["configured_baudrate"] == 250_000
    with pytest.raises(LsBusError, match="arbitration-lost behaviour 7"):
        bus.from_node(lsbus.encode([lsbus.Configuration(lsbus.ARBITRATION_LOST_BEHAVIOR, 7)]))


def test_bus_errors_take_the_node_through_error_passive_to_bus_off() -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    bus.start()
    bus.take()
    statuses = []
    sent = 0
    for _ in range(40):
        if bus.from_node(lsbus.encode([lsbus.CanTransmit(0x1A0, b"\x00")])):
            sent += 1
        bus.from_bus(ERROR_FRAME)     # the software bus's error rule destroys it
        for op in ops(bus):
            if isinstance(op, lsbus.Status):
                statuses.append(op.status)
            else:
                assert op == lsbus.BusError(0x1A0, lsbus.BIT_ERROR, lsbus.PRIMARY_ERROR_FLAG,
                                            True)
    assert statuses == [lsbus.ERROR_PASSIVE, lsbus.BUS_OFF]
    # TEC +8 per destroyed frame: passive after 16 (128 > 127), bus off after 32 (256 > 255)
    assert sent == 32 and bus.tec == 256
    assert bus.counts["dropped_bus_off"] == 8 and bus.counts["missed_bus_off"] == 8
    bus.from_bus(frame(0x181))                  # bus off: it hears nothing more
    assert not bus.pending()
    assert bus.record()["status"] == "bus off"


def test_receive_errors_alone_make_the_node_error_passive_not_bus_off() -> None:
    bus = CanNodeBus("CanChannel", notifications=True)
    for _ in range(300):
        bus.from_bus(ERROR_FRAME)
    found = [op for op in ops(bus) if isinstance(op, lsbus.Status)]
    assert found == [lsbus.Status(lsbus.ERROR_PASSIVE)] and bus.rec == 255
