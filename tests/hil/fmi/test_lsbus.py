"""FMI-LS-BUS 1.0 CAN operations: the layouts of fmi3LsBusCan.h, round trips, broken buffers."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.errors import FrameError
from hil.fmi import lsbus


def test_layouts_are_the_headers() -> None:
    # sizes asserted by the header's static_asserts, plus the data
    transmit = lsbus.encode([lsbus.CanTransmit(id=0x123, data=b"\x01\x02", ide=False)])
    assert transmit == struct.pack("<IIIBBH", 0x10, 18, 0x123, 0, 0, 2) + b"\x01\x02"
    assert len(lsbus.encode([lsbus.CanFdTransmit(id=1, data=b"")])) == 8 + 4 + 1 + 1 + 1 + 2
    assert len(lsbus.encode([lsbus.CanXlTransmit(id=1, data=b"")])) == 8 + 4 + 4 + 4 + 2
    assert lsbus.encode([lsbus.Confirm(0x7FF)]) == struct.pack("<III", 0x20, 12, 0x7FF)
    assert lsbus.encode([lsbus.ArbitrationLost(5)]) == struct.pack("<III", 0x30, 12, 5)
    assert lsbus.encode([lsbus.BusError(5, lsbus.CRC_ERROR, lsbus.PRIMARY_ERROR_FLAG, True)]) \
        == struct.pack("<IIIBBB", 0x31, 15, 5, 4, 1, 1)
    assert lsbus.encode([lsbus.Status(lsbus.BUS_OFF)]) == struct.pack("<IIB", 0x41, 9, 3)
    assert lsbus.encode([lsbus.Wakeup()]) == struct.pack("<II", 0x42, 8)
    # the header's CREATE_OP_CONFIGURATION_* lengths: header + type + the value
    assert lsbus.encode([lsbus.Configuration(lsbus.CAN_BAUDRATE, 250_000)]) == \
        struct.pack("<IIBI", 0x40, 13, 1, 250_000)
    assert lsbus.encode([lsbus.Configuration(lsbus.ARBITRATION_LOST_BEHAVIOR,
                                             lsbus.DISCARD_AND_NOTIFY)]) == \
        struct.pack("<IIBB", 0x40, 10, 4, 2)


OPS = st.one_of(
    st.builds(lsbus.CanTransmit, id=st.integers(0, 0x1FFFFFFF), data=st.binary(max_size=8),
              ide=st.booleans(), rtr=st.booleans()),
    st.builds(lsbus.CanFdTransmit, id=st.integers(0, 0x7FF), data=st.binary(max_size=64),
              ide=st.booleans(), brs=st.booleans(), esi=st.booleans()),
    st.builds(lsbus.CanXlTransmit, id=st.integers(0, 0x7FF), data=st.binary(max_size=100),
              sec=st.integers(0, 1), sdt=st.integers(0, 255), vcid=st.integers(0, 255),
              af=st.integers(0, 2**32 - 1)),
    st.builds(lsbus.Confirm, id=st.integers(0, 0x1FFFFFFF)),
    st.builds(lsbus.ArbitrationLost, id=st.integers(0, 0x1FFFFFFF)),
    st.builds(lsbus.BusError, id=st.integers(0, 0x1FFFFFFF), error_code=st.integers(1, 6),
              error_flag=st.integers(1, 2), is_sender=st.booleans()),
    st.builds(lsbus.Configuration, parameter=st.sampled_from([1, 2, 3]),
              value=st.integers(1, 10_000_000)),
    st.builds(lsbus.Configuration, parameter=st.just(4), value=st.integers(1, 2)),
    st.builds(lsbus.Status, status=st.integers(1, 3)),
    st.just(lsbus.Wakeup()),
    st.builds(lsbus.FormatError, data=st.binary(max_size=20)),
)


@given(st.lists(OPS, max_size=8))
def test_round_trip(ops: list[lsbus.Operation]) -> None:
    assert lsbus.decode(lsbus.encode(ops)) == ops


def test_an_unknown_code_is_kept_to_be_refused_by_name() -> None:
    [op] = lsbus.decode(struct.pack("<II", 0x99, 10) + b"ab")
    assert op == lsbus.Unknown(code=0x99, payload=b"ab")


@pytest.mark.parametrize("buffer, words", [
    (b"\x10\x00\x00", "not an operation header"),
    (struct.pack("<II", 0x10, 40) + b"x" * 8, "says length 40"),
    (struct.pack("<II", 0x10, 4), "says length 4"),
    (struct.pack("<IIIBBH", 0x10, 17, 1, 0, 0, 2) + b"\x01", "dataLength 2 but carries 1"),
    (struct.pack("<IIB", 0x20, 9, 1), "LS-BUS 1.0 says 12"),
    (struct.pack("<IIBH", 0x40, 11, 4, 1), "not one LS-BUS 1.0 defines"),
])
def test_a_broken_buffer_names_the_operation(buffer: bytes, words: str) -> None:
    with pytest.raises(FrameError, match=words) as info:
        lsbus.decode(buffer, where="CanChannel.Tx_Data")
    assert "CanChannel.Tx_Data" in str(info.value)
