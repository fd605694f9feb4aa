"""Binary form of the DDOP: exact round trips, field layout, malformed bytes named."""

import struct

import pytest

from hil.isobus import ddi
from hil.isobus.ddop import (
    DdopParseError,
    Device,
    DeviceElement,
    ElementType,
    ObjectPool,
    PoolBuilder,
    ProcessData,
    Property,
    ValuePresentation,
    parse_pool,
    serialise_object,
    serialise_pool,
)
from hil.isobus.ddop.samples import section_control_pool

NAME = 0xA00C80000AE00002


def test_device_object_layout_v4() -> None:
    dvc = Device(0, b"Seeder", b"1.0", NAME, b"123", b"ABCDEFG", b"en\x50\x00\x55\x55\xff",
                 b"EXT")
    data = serialise_object(dvc, version=4)
    assert data == (b"DVC" + b"\x00\x00" + b"\x06Seeder" + b"\x031.0"
                    + NAME.to_bytes(8, "little") + b"\x03123" + b"ABCDEFG"
                    + b"en\x50\x00\x55\x55\xff" + b"\x03EXT")
    # version 3 has no extended structure label: one length byte fewer
    v3 = serialise_object(Device(0, b"Seeder", b"1.0", NAME, b"123", b"ABCDEFG",
                                 b"en\x50\x00\x55\x55\xff"), version=3)
    assert len(v3) == len(data) - 4


def test_element_process_data_property_presentation_layouts() -> None:
    det = DeviceElement(9, ElementType.SECTION, b"S1", 4, 7, (10, 11))
    assert serialise_object(det) == (b"DET\x09\x00\x04\x02S1\x04\x00\x07\x00\x02\x00"
                                     b"\x0a\x00\x0b\x00")
    dpd = ProcessData(10, 6, 0x03, 0x09, b"Rate", 12)
    assert serialise_object(dpd) == b"DPD\x0a\x00\x06\x00\x03\x09\x04Rate\x0c\x00"
    dpt = Property(11, 134, -20, b"X", 0xFFFF)
    assert serialise_object(dpt) == b"DPT\x0b\x00\x86\x00\xec\xff\xff\xff\x01X\xff\xff"
    dvp = ValuePresentation(12, 0, 0.01, 2, b"kg/ha")
    assert serialise_object(dvp) == (b"DVP\x0c\x00\x00\x00\x00\x00" + struct.pack("<f", 0.01)
                                     + b"\x02\x05kg/ha")


@pytest.mark.parametrize("version", [3, 4])
@pytest.mark.parametrize("sections", [1, 4, 16, 17, 48])
def test_agisostack_style_pool_round_trips_exactly(version: int, sections: int) -> None:
    pool = section_control_pool(sections=sections, version=version)
    data = pool.to_bytes()
    again = ObjectPool.from_bytes(data, version=version)
    assert again.objects == pool.objects
    assert again.to_bytes() == data


def test_the_sample_pool_has_what_a_section_controller_declares() -> None:
    pool = section_control_pool(sections=4)
    boom = next(e for e in pool.elements if e.designator == b"Boom")
    sections = [e for e in pool.elements if e.element_type == ElementType.SECTION]
    assert [s.parent_id for s in sections] == [boom.object_id] * 4
    product = next(e for e in pool.elements if e.element_type == ElementType.BIN)
    for number, wanted in [(product.element_number, ddi.SETPOINT_MASS_PER_AREA_RATE),
                           (product.element_number, ddi.ACTUAL_MASS_PER_AREA_RATE),
                           (boom.element_number, ddi.SETPOINT_CONDENSED_WORK_STATE_1_16),
                           (boom.element_number, ddi.ACTUAL_CONDENSED_WORK_STATE_1_16),
                           (0, ddi.ACTUAL_WORK_STATE)]:
        assert pool.process_data(number, wanted) is not None, wanted
    assert pool.property_value(boom.element_number, ddi.SC_SETPOINT_TURN_ON_TIME) == 300
    assert pool.property_value(boom.element_number, ddi.SC_SETPOINT_TURN_OFF_TIME) == 200
    widths = [pool.property_value(s.element_number, ddi.ACTUAL_WORKING_WIDTH) for s in sections]
    assert widths == [500] * 4


def test_a_v3_pool_read_as_v4_fails_by_name_not_silently() -> None:
    data = section_control_pool(version=3).to_bytes()
    with pytest.raises(DdopParseError, match=r"DDOP"):
        parse_pool(data, version=4)


@pytest.mark.parametrize("cut", [1, 4, 7, 20, 40])
def test_a_truncated_pool_names_the_object_and_the_byte(cut: int) -> None:
    data = section_control_pool().to_bytes()
    with pytest.raises(DdopParseError) as info:
        parse_pool(data[:-cut])
    err = info.value
    assert err.offset is not None and err.offset <= len(data) - cut
    assert "DDOP" in str(err) and f"at byte {err.offset}" in str(err)


def test_a_truncated_object_names_its_id() -> None:
    data = serialise_object(ProcessData(0x1234, 6, 1, 8, b"Rate", 0xFFFF))
    with pytest.raises(DdopParseError, match=r"DDOP object 4660 at byte 10: DPD object ends "
                       r"after 3 of the 4 bytes of its designator"):
        parse_pool(data[:-3])


def test_an_unknown_table_id_is_named() -> None:
    with pytest.raises(DdopParseError, match=r"unknown table id b'XYZ'"):
        parse_pool(b"XYZ\x00\x00")


def test_the_empty_pool_parses_to_nothing() -> None:
    assert parse_pool(b"") == ()


def test_serialise_refuses_fields_that_do_not_fit() -> None:
    with pytest.raises(DdopParseError, match=r"structure label has 3 bytes"):
        serialise_object(Device(0, b"D", b"1", 0, b"", b"abc", b"en\x00\x00\x00\x00\xff"))
    with pytest.raises(DdopParseError, match=r"designator of 300 bytes"):
        serialise_object(ProcessData(1, 6, 0, 0, b"x" * 300))
    with pytest.raises(DdopParseError, match=r"version 3 pool has no extended"):
        serialise_object(Device(0, b"D", b"1", 0, b"", b"abcdefg", b"en\x00\x00\x00\x00\xff",
                                b"E"), version=3)


def test_builder_numbers_ids_and_elements_in_call_order() -> None:
    b = PoolBuilder()
    dvc = b.device("D", software_version="1", name=NAME)
    dev = b.element(ElementType.DEVICE, "D", parent=dvc)
    boom = b.element(ElementType.FUNCTION, "B", parent=dev)
    pd = b.process_data(boom, ddi=6, settable=True)
    pool = b.build()
    assert (dvc, dev, boom, pd) == (0, 1, 2, 3)
    assert [e.element_number for e in pool.elements] == [0, 1]
    assert pool.element(1) == DeviceElement(2, 2, b"B", 1, 1, (3,))
    assert pool.process_data(1, 6) == ProcessData(3, 6, 0x03, 0x08, b"", 0xFFFF)
    assert serialise_pool(pool.objects) == pool.to_bytes()


def test_an_element_with_more_than_255_children_keeps_its_16_bit_count() -> None:
    b = PoolBuilder()
    dvc = b.device("D", software_version="1", name=NAME)
    dev = b.element(ElementType.DEVICE, "D", parent=dvc)
    for i in range(300):
        b.property(dev, ddi=134, value=i)
    pool = b.build()
    data = pool.to_bytes()
    again = parse_pool(data)
    assert again == pool.objects
    element = next(o for o in again if isinstance(o, DeviceElement))
    assert len(element.children) == 300
