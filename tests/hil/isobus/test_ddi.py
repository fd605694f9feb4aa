"""The data dictionary table: entries checked against ISO 11783-11 figures, condensed states."""

import pytest

from hil.isobus import ddi


def test_the_entries_the_rig_needs_are_there() -> None:
    needed = [1, 2, 6, 7, 11, 12, 56, 57, 67, 70, 116, 117, 118, 119, 134, 135, 136, 141, 142,
              143, 158, 160, 205, 206, 289, 397, 0xDFFF, *range(161, 177), *range(290, 306)]
    missing = [n for n in needed if n not in ddi.DDI_TABLE]
    assert missing == []


@pytest.mark.parametrize(
    ("number", "unit", "resolution", "raw_min", "raw_max"),
    [
        (1, "mm³/m²", 0.01, 0, 2**31 - 1),
        (6, "mg/m²", 1.0, 0, 2**31 - 1),
        (11, "/m²", 0.001, 0, 2**31 - 1),
        (134, "mm", 1.0, -(2**31), 2**31 - 1),
        (141, "", 1.0, 0, 3),
        (161, "", 1.0, 0, 2**32 - 1),
        (305, "", 1.0, 0, 2**32 - 1),
        (205, "ms", 1.0, -(2**31), 2**31 - 1),
        (397, "mm/s", 1.0, -(2**31), 2**31 - 1),
    ],
)
def test_entries_match_the_dictionary(number: int, unit: str, resolution: float, raw_min: int,
                                      raw_max: int) -> None:
    entry = ddi.lookup(number)
    assert (entry.unit, entry.resolution, entry.raw_min, entry.raw_max) == (
        unit, resolution, raw_min, raw_max)


def test_numbers_are_unique_and_keyed_by_themselves() -> None:
    assert all(number == entry.number for number, entry in ddi.DDI_TABLE.items())
    assert len(ddi.DDI_TABLE) == len(ddi._ENTRIES)


def test_condensed_names_count_sections_in_sixteens() -> None:
    assert ddi.lookup(161).name == "Actual Condensed Work State (1-16)"
    assert ddi.lookup(176).name == "Actual Condensed Work State (241-256)"
    assert ddi.lookup(290).name == "Setpoint Condensed Work State (1-16)"
    assert ddi.lookup(305).name == "Setpoint Condensed Work State (241-256)"


def test_physical_and_raw_conversions() -> None:
    rate = ddi.lookup(ddi.SETPOINT_VOLUME_PER_AREA_RATE)
    assert rate.raw(123.45) == 12345
    assert rate.physical(12345) == pytest.approx(123.45)
    with pytest.raises(ValueError, match=r"DDI 1 .*outside"):
        rate.raw(-1.0)
    assert ddi.lookup(161).unsigned and not ddi.lookup(6).unsigned


def test_unknown_ddi_is_named() -> None:
    with pytest.raises(ddi.UnknownDdiError, match="DDI 4000 "):
        ddi.lookup(4000)
    assert ddi.name_of(0xE001) == "Proprietary DDI 57345"
    assert ddi.name_of(6) == "Setpoint Mass Per Area Application Rate"


def test_condensed_work_state_addressing() -> None:
    assert ddi.condensed_work_state_ddi(0, setpoint=True) == (290, 0)
    assert ddi.condensed_work_state_ddi(17, setpoint=False) == (162, 1)
    assert ddi.condensed_work_state_ddi(255, setpoint=True) == (305, 15)
    with pytest.raises(ValueError):
        ddi.condensed_work_state_ddi(256, setpoint=True)


def test_condensed_pack_fills_missing_sections_with_not_installed() -> None:
    value = ddi.pack_condensed_work_state([1, 0, 1, 1])
    assert value & 0xFF == 0b01_01_00_01
    assert value >> 8 == 0xFFFFFF
    assert ddi.unpack_condensed_work_state(value)[:5] == [1, 0, 1, 1, 3]
    with pytest.raises(ValueError):
        ddi.pack_condensed_work_state([4])
