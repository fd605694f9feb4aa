"""Process data codec: the bytes of each message, round trips, malformed payloads named."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.errors import FrameError
from hil.isobus import process_data as pd
from hil.isobus.process_data import Command, decode, encode

FF = 0xFF

# (message, the payload ISO 11783-10 gives it, as AgIsoStack++'s client and server send it)
VECTORS: list[tuple[pd.ProcessDataMessage, bytes]] = [
    (pd.RequestVersion(), bytes([0x00, FF, FF, FF, FF, FF, FF, FF])),
    (pd.Version(4, pd.VersionOption.IMPLEMENT_SECTION_CONTROL
                | pd.VersionOption.TC_GEO_WITH_POSITION_BASED_CONTROL, 1, 16, 1),
     bytes([0x10, 4, FF, 0x14, 0x00, 1, 16, 1])),
    (pd.IdentifyTaskController(), bytes([0x20, FF, FF, FF, FF, FF, FF, FF])),
    (pd.RequestStructureLabel(), bytes([0x01, FF, FF, FF, FF, FF, FF, FF])),
    (pd.StructureLabel(b"AGRIHIL"), b"\x11AGRIHIL"),
    (pd.StructureLabel(b"AGRIHIL", b"EXTENDED"), b"\x11AGRIHILEXTENDED"),
    (pd.RequestLocalizationLabel(), bytes([0x21, FF, FF, FF, FF, FF, FF, FF])),
    (pd.LocalizationLabel(b"en\x50\x00\x55\x55\xff"), b"\x31en\x50\x00\x55\x55\xff"),
    (pd.RequestObjectPoolTransfer(1073), bytes([0x41, 0x31, 0x04, 0, 0, FF, FF, FF])),
    (pd.RequestObjectPoolTransferResponse(True), bytes([0x51, 0, FF, FF, FF, FF, FF, FF])),
    (pd.RequestObjectPoolTransferResponse(False), bytes([0x51, 1, FF, FF, FF, FF, FF, FF])),
    (pd.ObjectPoolTransfer(b"DVC\x00\x00"), b"\x61DVC\x00\x00"),
    (pd.ObjectPoolTransferResponse(0, 1073), bytes([0x71, 0, 0x31, 0x04, 0, 0, FF, FF])),
    (pd.ObjectPoolActivate(True), bytes([0x81, 0xFF, FF, FF, FF, FF, FF, FF])),
    (pd.ObjectPoolActivate(False), bytes([0x81, 0x00, FF, FF, FF, FF, FF, FF])),
    (pd.ObjectPoolActivateResponse(0), bytes([0x91, 0, FF, FF, FF, FF, 0, FF])),
    (pd.ObjectPoolActivateResponse(0x01, 0x0009, 0x1234, 0x02),
     bytes([0x91, 0x01, 0x09, 0x00, 0x34, 0x12, 0x02, FF])),
    (pd.DeleteObjectPool(), bytes([0xA1, FF, FF, FF, FF, FF, FF, FF])),
    (pd.DeleteObjectPoolResponse(True), bytes([0xB1, 0, FF, FF, FF, FF, FF, FF])),
    (pd.ElementCommand(Command.REQUEST_VALUE, 0x123, 7), bytes([0x32, 0x12, 7, 0, FF, FF, FF, FF])),
    (pd.ElementCommand(Command.VALUE, 2, 6, 25000), bytes([0x23, 0x00, 6, 0, 0xA8, 0x61, 0, 0])),
    (pd.ElementCommand(Command.VALUE, 4095, 290, -1431655766),
     bytes([0xF3, 0xFF, 0x22, 0x01, 0xAA, 0xAA, 0xAA, 0xAA])),
    (pd.ElementCommand(Command.MEASUREMENT_TIME_INTERVAL, 3, 7, 1000),
     bytes([0x34, 0, 7, 0, 0xE8, 0x03, 0, 0])),
    (pd.ElementCommand(Command.MEASUREMENT_DISTANCE_INTERVAL, 3, 7, 5000),
     bytes([0x35, 0, 7, 0, 0x88, 0x13, 0, 0])),
    (pd.ElementCommand(Command.MEASUREMENT_MINIMUM_THRESHOLD, 3, 7, 1),
     bytes([0x36, 0, 7, 0, 1, 0, 0, 0])),
    (pd.ElementCommand(Command.MEASUREMENT_MAXIMUM_THRESHOLD, 3, 7, 2),
     bytes([0x37, 0, 7, 0, 2, 0, 0, 0])),
    (pd.ElementCommand(Command.MEASUREMENT_CHANGE_THRESHOLD, 3, 7, 3),
     bytes([0x38, 0, 7, 0, 3, 0, 0, 0])),
    (pd.ElementCommand(Command.SET_VALUE_AND_ACKNOWLEDGE, 1, 289, 1),
     bytes([0x1A, 0, 0x21, 0x01, 1, 0, 0, 0])),
    (pd.ProcessDataAcknowledge(1, 289, pd.AckError.NOT_SETTABLE, Command.SET_VALUE_AND_ACKNOWLEDGE),
     bytes([0x1D, 0, 0x21, 0x01, 0x10, 0xFA, FF, FF])),
    (pd.TaskControllerStatus(), bytes([0xFE, FF, FF, FF, 0, 0, 0, FF])),
    (pd.TaskControllerStatus(pd.ServerStatus.BUSY_EXECUTING_COMMAND, 0x81, 0x61),
     bytes([0xFE, FF, FF, FF, 0x08, 0x81, 0x61, FF])),
    (pd.ClientTask(False), bytes([0xFF, FF, FF, FF, 0, 0, 0, 0])),
    (pd.ClientTask(True, 1), bytes([0xFF, FF, FF, FF, 1, 0, 0, 0])),
]


@pytest.mark.parametrize(("message", "payload"), VECTORS,
                         ids=[type(m).__name__ for m, _ in VECTORS])
def test_each_message_has_the_standard_bytes_and_round_trips(
        message: pd.ProcessDataMessage, payload: bytes) -> None:
    assert encode(message) == payload
    assert decode(payload) == message


def test_working_set_master() -> None:
    assert pd.encode_working_set_master(pd.WorkingSetMaster(1)) == bytes([1] + [FF] * 7)
    assert pd.decode_working_set_master(bytes([2] + [FF] * 7)) == pd.WorkingSetMaster(2)
    with pytest.raises(FrameError, match="0 members"):
        pd.decode_working_set_master(bytes([0] + [FF] * 7))
    with pytest.raises(FrameError, match="3 bytes, not 8"):
        pd.decode_working_set_master(b"\x01\xff\xff")


def test_unsigned_view_of_a_condensed_work_state() -> None:
    msg = decode(bytes([0xF3, 0xFF, 0x22, 0x01, 0xAA, 0xAA, 0xAA, 0xAA]))
    assert isinstance(msg, pd.ElementCommand) and msg.unsigned == 0xAAAAAAAA
    assert encode(pd.ElementCommand(Command.VALUE, 4095, 290, 0xAAAAAAAA)) == encode(msg)


@pytest.mark.parametrize(("payload", "words"), [
    (b"", "empty"),
    (bytes([0x03, 0, 6, 0]), "4 bytes, at least 8"),
    (bytes([0x0B] + [FF] * 7), "command 0xB is reserved"),
    (bytes([0x0C] + [FF] * 7), "command 0xC is reserved"),
    (bytes([0x09] + [FF] * 7), "command 0x9 is reserved or not supported"),
    (bytes([0x30] + [FF] * 7), "technical capabilities sub-command 3"),
    (bytes([0xE1] + [FF] * 7), "device descriptor sub-command 14"),
    (bytes([0x81, 0x12] + [FF] * 6), "neither 0xFF"),
])
def test_malformed_payloads_raise_frame_errors_naming_the_bytes(payload: bytes, words: str) -> None:
    with pytest.raises(FrameError, match=words):
        decode(payload)


def test_encode_refuses_what_does_not_fit() -> None:
    with pytest.raises(FrameError, match="element number 4096"):
        encode(pd.ElementCommand(Command.VALUE, 4096, 6, 0))
    with pytest.raises(FrameError, match="7 bytes, not 3"):
        encode(pd.StructureLabel(b"abc"))
    with pytest.raises(FrameError, match="not an element command"):
        encode(pd.ElementCommand(Command.STATUS, 1, 6, 0))
    with pytest.raises(FrameError, match="does not fit"):
        encode(pd.ElementCommand(Command.VALUE, 1, 70000, 0))


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.binary(min_size=0, max_size=12))
def test_decode_never_crashes_and_element_commands_round_trip(data: bytes) -> None:
    try:
        msg = decode(data)
    except FrameError:
        return
    again = encode(msg)
    if isinstance(msg, pd.ElementCommand | pd.ObjectPoolTransfer):
        assert again == data[:8] if isinstance(msg, pd.ElementCommand) else again == data
    assert decode(again) == msg
