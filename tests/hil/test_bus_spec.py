from __future__ import annotations

import can
import pytest

from hil.bus import available_transports, open_bus, parse_spec, register_transport
from hil.bus.spec import BusSpec
from hil.bus.transports import kernel_has_socketcan
from hil.errors import BusError, BusSpecError


@pytest.mark.parametrize(("text", "transport", "channel", "options"), [
    ("virtual", "virtual", None, {}),
    ("virtual:rig1", "virtual", "rig1", {}),
    ("socketcan:vcan0", "socketcan", "vcan0", {}),
    ("socketcand:127.0.0.1:29536/can0", "socketcand", "127.0.0.1:29536/can0", {}),
    ("pcan:PCAN_USBBUS1,bitrate=250000", "pcan", "PCAN_USBBUS1", {"bitrate": 250000}),
    ("slcan:/dev/ttyACM0,bitrate=250000,sleep_after_open=0.5", "slcan", "/dev/ttyACM0",
     {"bitrate": 250000, "sleep_after_open": 0.5}),
    ("virtual:x,receive_own_messages=true", "virtual", "x", {"receive_own_messages": True}),
])
def test_parse_spec(text: str, transport: str, channel: str | None, options: dict) -> None:
    spec = parse_spec(text)
    assert (spec.transport, spec.channel, spec.options) == (transport, channel, options)


@pytest.mark.parametrize("text", ["", "   ", "9bad:x", "virtual,notkv", "virtual:x,=3"])
def test_bad_specs_are_refused(text: str) -> None:
    with pytest.raises(BusSpecError):
        parse_spec(text)


def test_unknown_transport_lists_what_is_available() -> None:
    with pytest.raises(BusSpecError) as err:
        open_bus("carrierpigeon:loft1")
    message = str(err.value)
    assert "carrierpigeon" in message
    for name in ("virtual", "socketcan", "socketcand", "pcan"):
        assert name in message
    assert set(available_transports()) >= {"virtual", "socketcan", "socketcand", "kvaser"}


def test_virtual_buses_on_one_channel_talk() -> None:
    a, b = open_bus("virtual:test_spec"), open_bus("virtual:test_spec")
    try:
        a.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))
        msg = b.recv(1.0)
        assert msg is not None and msg.arbitration_id == 0x123
    finally:
        a.shutdown()
        b.shutdown()


def test_registered_transport_is_used() -> None:
    seen: list[BusSpec] = []

    def opener(spec: BusSpec) -> can.BusABC:
        seen.append(spec)
        return can.Bus(interface="virtual", channel="registered")

    register_transport("mytransport", opener)
    bus = open_bus("mytransport:abc,speed=3")
    bus.shutdown()
    assert seen == [BusSpec("mytransport", "abc", {"speed": 3})]


def test_socketcand_spec_needs_host_and_port() -> None:
    with pytest.raises(BusSpecError, match="host and port"):
        open_bus("socketcand:localhost")


def test_socketcand_without_server_fails_fast_and_clearly() -> None:
    with pytest.raises(BusError, match=r"no software bus .*hil bus serve"):
        open_bus("socketcand:127.0.0.1:1/can0")


def test_socketcan_error_is_clear_where_the_kernel_has_none() -> None:
    ok, _why = kernel_has_socketcan()
    if ok:
        pytest.skip("this kernel has SocketCAN; the refusal path cannot be seen here")
    with pytest.raises(BusError, match="software bus"):
        open_bus("socketcan:vcan0")
