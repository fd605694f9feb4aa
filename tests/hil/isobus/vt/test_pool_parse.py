"""VT object pools: every type parses and serialises back; faults are named as the standard says."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.codec import parse_objects, serialise_object
from hil.isobus.vt.errors import NO_OBJECT, PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import ATTRIBUTE_IDS, INTRODUCED_IN, LAYOUTS, ObjectType
from hil.isobus.vt.pool import ObjectPool

T = ObjectType


def every_type_pool(version: int = 6) -> PoolBuilder:
    """A pool with at least one object of every type the version has, all references whole."""
    b = PoolBuilder(version=version)
    font = b.font(size=4)
    line = b.add(T.LINE_ATTRIBUTES, line_width=1, line_art=0xFFFF)
    pic = b.add(T.PICTURE_GRAPHIC, width=4, actual_width=4, actual_height=2, format=2,
                raw_data=bytes(range(8)))
    fill = b.add(T.FILL_ATTRIBUTES, fill_type=2, fill_colour=3)
    b.add(T.FILL_ATTRIBUTES, fill_type=3, fill_pattern=pic)
    numvar = b.number_variable(42)
    strvar = b.string_variable("hello")
    inattr = b.add(T.INPUT_ATTRIBUTES, validation_string=b"0123456789")
    macro = b.macro(bytes([0xA0, 0x01, 0x00, 0x01, 0xFF, 0xFF, 0xFF, 0xFF]))
    label = b.output_string("Go", font=font, macros=[(9, macro)])
    drawn = [
        b.output_number(numvar, font=font, scale=0.1, decimals=1),
        b.input_number(numvar, font=font),
        b.input_string(strvar, font=font, input_attributes=inattr),
        b.add(T.INPUT_BOOLEAN, foreground_colour=font, variable_reference=numvar, width=20),
        b.add(T.INPUT_LIST, width=50, height=20, items=[label, NO_OBJECT]),
        b.add(T.OUTPUT_LINE, line_attributes=line, width=10, height=10, line_direction=1),
        b.rectangle(30, 20, line=line, fill=fill),
        b.add(T.OUTPUT_ELLIPSE, line_attributes=line, width=30, height=20, end_angle=180,
              fill_attributes=fill),
        b.add(T.OUTPUT_POLYGON, width=30, height=30, line_attributes=line,
              points=[(0, 0), (30, 0), (15, 30)]),
        b.add(T.OUTPUT_METER, width=60, max_value=100, variable_reference=numvar,
              end_angle=180),
        b.add(T.OUTPUT_LINEAR_BAR_GRAPH, width=10, height=60, max_value=100, value=30),
        b.add(T.OUTPUT_ARCHED_BAR_GRAPH, width=60, height=60, max_value=100, end_angle=180),
        pic,
        b.add(T.OBJECT_POINTER, value=label),
        b.button(label, key_code=5),
        b.container([(label, 0, 0)], 40, 20),
        b.add(T.OUTPUT_LIST, width=50, height=20, items=[label]),
        b.add(T.GRAPHICS_CONTEXT, viewport_width=20, viewport_height=20, canvas_width=20,
              canvas_height=20, font_attributes=font),
        b.add(T.AUXILIARY_FUNCTION_2, children=[(label, 0, 0)]),
        b.add(T.AUXILIARY_INPUT_2, children=[(label, 0, 0)]),
    ]
    if version >= 5:
        drawn.append(b.add(T.ANIMATION, width=20, height=20, children=[(label, 0, 0)]))
    if version >= 6:
        gd = b.add(T.GRAPHIC_DATA, data=b"\x89PNG....")
        drawn.append(b.add(T.SCALED_GRAPHIC, width=20, height=20, value=gd))
        palette = b.add(T.COLOUR_PALETTE, colours=[b"\x00\x00\xff\xff"] * 2)
        cmap = b.add(T.COLOUR_MAP, indexes=bytes(range(16)))
        b.add(T.WORKING_SET_SPECIAL_CONTROLS, colour_map=cmap, colour_palette=palette,
              language_pairs=[b"deDE"])
    else:
        b.add(T.COLOUR_MAP, indexes=bytes(range(16)))
    aux2 = drawn[-3] if version >= 5 else drawn[-2]
    b.add(T.AUXILIARY_CONTROL_DESIGNATOR_2, auxiliary_object_id=aux2)
    b.add(T.AUXILIARY_FUNCTION_1, children=[(label, 0, 0)])
    b.add(T.AUXILIARY_INPUT_1, children=[(label, 0, 0)], input_id=3)
    key = b.key(label, key_code=1)
    keys = b.soft_key_mask([key])
    b.add(T.KEY_GROUP, keys=[key], name=label)
    b.add(T.WINDOW_MASK, window_width=1, window_height=1, object_refs=[label])
    b.add(T.EXTENDED_INPUT_ATTRIBUTES, code_planes=[bytes([0, 1, 0x30, 0, 0x39, 0])])
    b.add(T.OBJECT_LABEL_REFERENCE_LIST, labels=[bytes(7)])
    ref_name = b.add(T.EXTERNAL_REFERENCE_NAME, name=0xA00C80000AE00002)
    b.add(T.EXTERNAL_OBJECT_DEFINITION, name=0xA00C80000AE00002, objects=[label])
    b.add(T.EXTERNAL_OBJECT_POINTER, default_object=label, external_reference_name=ref_name,
          external_object=label)
    alarm = b.alarm_mask([(label, 0, 0)], soft_key_mask=keys, priority=0)
    mask = b.data_mask([(o, i, i) for i, o in enumerate(drawn)] + [(key, 0, 0)],
                       soft_key_mask=keys)
    b.working_set(mask, children=[(label, 0, 0)], languages=[b"en", b"de"])
    assert alarm
    return b


@pytest.mark.parametrize("version", [4, 5, 6])
def test_every_type_of_the_version_parses_and_serialises_back(version: int) -> None:
    b = every_type_pool(version)
    pool = b.build()
    types = {o.type for o in pool}
    assert types == {t for t in ObjectType if INTRODUCED_IN[t] <= version}
    again = ObjectPool.from_transfers([pool.to_bytes()], version)
    for obj in again:
        assert serialise_object(obj) == serialise_object(pool.objects[obj.object_id])
    assert again.to_bytes() == pool.to_bytes()
    assert pool.get(pool.working_set.object_id)["languages"] == [b"en", b"de"]


def test_values_read_back_as_written() -> None:
    b = PoolBuilder()
    var = b.number_variable(123456)
    out = b.output_number(var, scale=0.001, decimals=3, offset=-5)
    pool_bytes = b"".join(serialise_object(o) for o in b.objects)
    parsed = {o.object_id: o for o in parse_objects(pool_bytes)}
    assert parsed[var]["value"] == 123456
    assert parsed[out]["offset"] == -5
    assert parsed[out]["decimals"] == 3
    assert abs(parsed[out]["scale"] - 0.001) < 1e-9


def _refused(data: bytes, version: int = 4) -> VtPoolError:
    with pytest.raises(VtPoolError) as info:
        ObjectPool.from_transfers([data], version)
    return info.value


def _small(**overrides: object) -> PoolBuilder:
    b = PoolBuilder()
    font = b.font()
    label = b.output_string("x", font=font, object_id=100)
    mask = b.data_mask([(label, 0, 0)], object_id=1000)
    b.working_set(mask, object_id=0)
    return b


def test_unknown_type_is_not_supported_naming_the_object() -> None:
    b = _small()
    data = b"".join(serialise_object(o) for o in b.objects) + bytes([0x34, 0x12, 99, 0, 0])
    err = _refused(data)
    assert err.code == PoolErrorCode.NOT_SUPPORTED
    assert err.object_id == 0x1234
    assert "unknown object type 99" in str(err)
    assert err.response() == bytes([0x12, 0x01, 0xFF, 0xFF, 0x34, 0x12, 0x01, 0xFF])


def test_a_type_newer_than_the_vt_is_not_supported() -> None:
    b = _small()
    b.add(T.ANIMATION, object_id=555, width=1, height=1)
    data = b"".join(serialise_object(o) for o in b.objects)
    err = _refused(data, version=4)
    assert (err.code, err.object_id) == (PoolErrorCode.NOT_SUPPORTED, 555)
    assert "needs VT version 5" in str(err)
    assert ObjectPool.from_transfers([data], 5).get(555) is not None


def test_missing_reference_names_the_object_and_its_parent() -> None:
    b = _small()
    b.objects[1].attrs["font_attributes"] = 4321     # the label's font does not exist
    data = b"".join(serialise_object(o) for o in b.objects)
    err = _refused(data)
    assert err.code == PoolErrorCode.UNKNOWN_REFERENCE
    assert (err.object_id, err.parent_id) == (100, 1000)
    assert "4321" in str(err)
    assert err.response()[2:7] == bytes([0xE8, 0x03, 100, 0, 0x02])


def test_missing_child_and_missing_active_mask() -> None:
    b = _small()
    b.objects[2].attrs["children"].append((777, 0, 0))
    err = _refused(b"".join(serialise_object(o) for o in b.objects))
    assert (err.code, err.object_id) == (PoolErrorCode.UNKNOWN_REFERENCE, 1000)
    b = _small()
    b.objects[3].attrs["active_mask"] = 999
    err = _refused(b"".join(serialise_object(o) for o in b.objects))
    assert (err.code, err.object_id) == (PoolErrorCode.UNKNOWN_REFERENCE, 0)


def test_bad_attribute_is_not_supported() -> None:
    b = _small()
    b.objects[0].attrs["font_type"] = 3              # reserved font type
    err = _refused(b"".join(serialise_object(o) for o in b.objects))
    assert (err.code, err.object_id) == (PoolErrorCode.NOT_SUPPORTED, 1)
    assert "font_type = 3" in str(err)


def test_reference_to_the_wrong_type_is_any_other_error() -> None:
    b = _small()
    b.objects[1].attrs["font_attributes"] = 1000     # a data mask, not font attributes
    err = _refused(b"".join(serialise_object(o) for o in b.objects))
    assert (err.code, err.object_id) == (PoolErrorCode.ANY_OTHER, 100)


def test_truncated_object_and_duplicate_id() -> None:
    b = _small()
    data = b"".join(serialise_object(o) for o in b.objects)
    err = _refused(data[:-3])
    assert (err.code, err.object_id) == (PoolErrorCode.ANY_OTHER, 0)
    dup = data + serialise_object(b.objects[0])
    err = _refused(dup)
    assert (err.code, err.object_id) == (PoolErrorCode.ANY_OTHER, 1)
    assert "twice" in str(err)


def test_no_working_set_object() -> None:
    b = _small()
    data = b"".join(serialise_object(o) for o in b.objects[:-1])
    err = _refused(data)
    assert "0 working set objects" in str(err)


def test_several_transfers_a_later_one_replaces_objects() -> None:
    b = _small()
    parts = [serialise_object(o) for o in b.objects]
    changed = b.objects[1]
    changed.attrs["value"] = b"replaced"
    pool = ObjectPool.from_transfers([b"".join(parts[:2]), b"".join(parts[2:]),
                                      serialise_object(changed)])
    assert pool.get(100)["value"] == b"replaced"
    assert len(pool.raw) == 3


def test_extended_macro_reference_from_version_5() -> None:
    b = PoolBuilder(version=5)
    macro = b.macro(bytes([0xBE, 1, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]), object_id=300)
    label = b.output_string("x", macros=[(1, macro)], object_id=10)
    b.working_set(b.data_mask([(label, 0, 0)]))
    pool = b.build()
    assert pool.get(10)["macros"] == [(1, 300)]
    raw = serialise_object(pool.get(10))
    assert bytes([0xFF, 300 & 0xFF, 1, 300 >> 8]) in raw


def test_change_attribute_ids_follow_the_standard_tables() -> None:
    number = ATTRIBUTE_IDS[T.OUTPUT_NUMBER]
    assert [number[i].name for i in range(1, 12)] == [
        "width", "height", "background_colour", "font_attributes", "options",
        "variable_reference", "offset", "scale", "decimals", "format", "justification"]
    assert [f.name for f in ATTRIBUTE_IDS[T.OUTPUT_RECTANGLE].values()] == [
        "line_attributes", "width", "height", "line_suppression", "fill_attributes"]
    assert set(LAYOUTS) == set(ObjectType)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_any_bytes_give_a_pool_or_a_named_refusal(data: bytes) -> None:
    try:
        ObjectPool.from_transfers([data], 6)
    except VtPoolError as err:
        assert err.code in PoolErrorCode


EXAMPLE_POOL = os.environ.get("AGRIHIL_VT_EXAMPLE_POOL")


@pytest.mark.skipif(not EXAMPLE_POOL, reason="set AGRIHIL_VT_EXAMPLE_POOL to AgIsoStack++'s "
                    "examples/virtual_terminal/version3_object_pool/VT3TestPool.iop")
def test_agisostack_version3_example_pool() -> None:
    data = Path(str(EXAMPLE_POOL)).read_bytes()
    pool = ObjectPool.from_transfers([data], 3)
    counts = pool.counts()
    assert counts["working_set"] == 1 and counts["soft_key_mask"] >= 1
    assert counts["alarm_mask"] >= 1 and counts["picture_graphic"] >= 1
    assert b"".join(serialise_object(o) for o in pool) == data


@pytest.mark.skipif(not EXAMPLE_POOL, reason="set AGRIHIL_VT_EXAMPLE_POOL (see above)")
def test_agisostack_version3_example_pool_is_drawn() -> None:
    from hil.isobus.vt.render import render
    from hil.isobus.vt.workingset import WorkingSet

    pool = ObjectPool.from_transfers([Path(str(EXAMPLE_POOL)).read_bytes()], 3)
    image = render(WorkingSet(1, 1, None, 0.0, 0.0, pool=pool))
    colours = image.getcolors(1 << 20)
    assert colours is not None and len(colours) > 20      # text, pictures, soft keys
