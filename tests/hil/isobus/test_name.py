"""The 64-bit ISO 11783-5 NAME: layout, bytes, order, bad fields."""

from __future__ import annotations

import j1939
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.errors import FrameError
from hil.isobus.name import NAME_LAYOUT, IsobusName

FIELDS = {
    "identity_number": 123456, "manufacturer_code": 789, "ecu_instance": 6,
    "function_instance": 5, "function": 130, "device_class": 4, "device_class_instance": 3,
    "industry_group": 2, "self_configurable": True,
}


def test_each_field_lands_on_its_bits() -> None:
    for field, shift, width in NAME_LAYOUT:
        top = (1 << width) - 1
        kwargs = {f: 0 for f, _, _ in NAME_LAYOUT}
        kwargs[field] = top if field != "self_configurable" else True
        name = IsobusName(**kwargs)
        assert name.value == top << shift, field


def test_matches_can_j1939_name_bit_for_bit() -> None:
    ours = IsobusName(**FIELDS)
    theirs = j1939.Name(arbitrary_address_capable=1, industry_group=2,
                        vehicle_system_instance=3, vehicle_system=4, function=130,
                        function_instance=5, ecu_instance=6, manufacturer_code=789,
                        identity_number=123456)
    assert ours.value == theirs.value
    assert list(ours.to_bytes()) == theirs.bytes


def test_bytes_are_little_endian() -> None:
    name = IsobusName(identity_number=1)
    assert name.to_bytes() == bytes([1, 0, 0, 0, 0, 0, 0, 0x20])  # group 2 in bits 60-62


@settings(deadline=None)     # no wall-clock limit: the machine is shared
@given(st.integers(0, 2**64 - 1))
def test_round_trip_of_any_name_but_the_reserved_bit(value: int) -> None:
    name = IsobusName.from_int(value)
    assert name.value == value & ~(1 << 48)
    assert IsobusName.from_bytes(name.to_bytes()) == name


def test_lower_name_wins_and_self_configurable_bit_counts_most() -> None:
    low = IsobusName(identity_number=5)
    high = IsobusName(identity_number=6)
    assert low < high and not high < low and sorted([high, low]) == [low, high]
    fixed = IsobusName(identity_number=2**21 - 1, function=255)
    arbitrary = IsobusName(identity_number=0, self_configurable=True)
    assert fixed < arbitrary


@pytest.mark.parametrize(("field", "value"), [("identity_number", 2**21),
                                              ("function", 256), ("ecu_instance", 8),
                                              ("industry_group", -1)])
def test_a_field_too_wide_is_refused_by_name(field: str, value: int) -> None:
    with pytest.raises(FrameError, match=field):
        IsobusName(**{field: value})


def test_wrong_length_is_refused() -> None:
    with pytest.raises(FrameError, match="7 bytes"):
        IsobusName.from_bytes(bytes(7))
