from __future__ import annotations

import pytest

from hil.softbus.protocol import (
    Frame,
    MessageSplitter,
    ProtocolError,
    format_frame,
    format_send,
    parse_send,
)


def test_send_round_trip_standard_and_extended() -> None:
    for frame in (Frame(0x123, b"\x01\x02", False), Frame(0x18FEF100, bytes(8), True),
                  Frame(0x7FF, b"", False)):
        assert parse_send(format_send(frame).decode()[7:-2]) == frame


def test_frame_format_is_what_python_can_parses() -> None:
    from can.interfaces.socketcand.socketcand import convert_ascii_message_to_can_message
    line = format_frame(Frame(0x18FEF100, b"\xde\xad", True), 12.5).decode()
    msg = convert_ascii_message_to_can_message(line)
    assert msg.arbitration_id == 0x18FEF100 and msg.is_extended_id
    assert bytes(msg.data) == b"\xde\xad" and msg.timestamp == 12.5
    empty = convert_ascii_message_to_can_message(format_frame(Frame(0x80, b"", False), 1).decode())
    assert empty.arbitration_id == 0x80 and not empty.is_extended_id and empty.dlc == 0


@pytest.mark.parametrize("body", ["123", "123 2 01", "12G 1 00", "123 1 100",
                                  "800 0", "123 9 1 2 3 4 5 6 7 8 9"])
def test_bad_send_is_refused(body: str) -> None:
    with pytest.raises(ProtocolError):
        parse_send(body)


def test_splitter_handles_partial_and_joined_messages() -> None:
    s = MessageSplitter()
    assert s.feed(b"< hi >< open c") == ["hi"]
    assert s.feed(b"an0 >junk< rawmode >") == ["open can0", "rawmode"]
    with pytest.raises(ProtocolError):
        s.feed(b"<" + b"x" * 600)
