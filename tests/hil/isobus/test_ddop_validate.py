"""Every DDOP rule the TC enforces fires on a pool that breaks it, naming the object."""

from collections.abc import Callable
from dataclasses import replace

import pytest

from hil.isobus.ddop import (
    DdopError,
    DdopObject,
    Device,
    DeviceElement,
    ElementType,
    PoolError,
    ProcessData,
    Property,
    ValuePresentation,
    check,
    problems,
)
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.ddop.validate import duplicate_ids

Objects = list[DdopObject]


def _base() -> Objects:
    return list(section_control_pool(sections=2).objects)


def _find(objs: Objects, kind: type, **fields: object) -> int:
    for i, obj in enumerate(objs):
        if isinstance(obj, kind) and all(getattr(obj, k) == v for k, v in fields.items()):
            return i
    raise LookupError(kind)


def _edit(kind: type, change: Callable[[DdopObject], DdopObject], **fields: object,
          ) -> Callable[[Objects], Objects]:
    def apply(objs: Objects) -> Objects:
        i = _find(objs, kind, **fields)
        objs[i] = change(objs[i])
        return objs
    return apply


def _append(obj: DdopObject) -> Callable[[Objects], Objects]:
    return lambda objs: [*objs, obj]


def _drop(kind: type, **fields: object) -> Callable[[Objects], Objects]:
    def apply(objs: Objects) -> Objects:
        del objs[_find(objs, kind, **fields)]
        return objs
    return apply


# (id, mutation, offending object id, error bit, words in the reason)
BOOM = next(o.object_id for o in section_control_pool(sections=2).objects
            if isinstance(o, DeviceElement) and o.designator == b"Boom")
CASES: list[tuple[str, Callable[[Objects], Objects], int | None, PoolError, str]] = [
    ("null id", _append(ValuePresentation(0xFFFF, 0, 1.0, 0, b"x")), 0xFFFF,
     PoolError.ANY_OTHER_ERROR, "null object id"),
    ("duplicate id", _append(ValuePresentation(1, 0, 1.0, 0, b"x")), 1,
     PoolError.ANY_OTHER_ERROR, "duplicate object id"),
    ("no device", _drop(Device), None, PoolError.ANY_OTHER_ERROR, "no device object"),
    ("two devices", _append(Device(900, b"D", b"1", 0, b"", b"ABCDEFG",
                                   b"en\x00\x00\x00\x00\xff")), 900,
     PoolError.ANY_OTHER_ERROR, "second device object"),
    ("designator too long", _edit(ProcessData, lambda o: replace(o, designator=b"x" * 33),
                                  ddi=6), None, PoolError.ANY_OTHER_ERROR, "33 characters"),
    ("designator not utf-8", _edit(DeviceElement, lambda o: replace(o, designator=b"\xff\xfe"),
                                   element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "not UTF-8"),
    ("software version too long",
     _edit(Device, lambda o: replace(o, software_version=b"1" * 40)), 0,
     PoolError.ANY_OTHER_ERROR, "software version has 40"),
    ("extended label too long",
     _edit(Device, lambda o: replace(o, extended_structure_label=b"e" * 33)), 0,
     PoolError.ANY_OTHER_ERROR, "extended structure label has 33"),
    ("no device element", _edit(DeviceElement, lambda o: replace(o, element_type=2),
                                element_type=ElementType.DEVICE), 0,
     PoolError.ANY_OTHER_ERROR, "no device element of type 1"),
    ("two device elements", _edit(DeviceElement, lambda o: replace(o, element_type=1),
                                  element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "second device element"),
    ("element type unknown", _edit(DeviceElement, lambda o: replace(o, element_type=9),
                                   element_type=ElementType.BIN), None,
     PoolError.METHOD_OR_ATTRIBUTE_NOT_SUPPORTED, "element type 9"),
    ("element number clash", _edit(DeviceElement, lambda o: replace(o, element_number=1),
                                   element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "element number 1 is also element object"),
    ("element number too big", _edit(DeviceElement, lambda o: replace(o, element_number=4096),
                                     element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "exceeds 4095"),
    ("device element parent not the device",
     _edit(DeviceElement, lambda o: replace(o, parent_id=BOOM), element_type=1), 4,
     PoolError.ANY_OTHER_ERROR, "must be the device object"),
    ("device element parent missing",
     _edit(DeviceElement, lambda o: replace(o, parent_id=7777), element_type=1), 4,
     PoolError.UNKNOWN_OBJECT_REFERENCE, "must be the device object, not nothing"),
    ("dangling parent", _edit(DeviceElement, lambda o: replace(o, parent_id=7777),
                              element_type=ElementType.BIN), None,
     PoolError.UNKNOWN_OBJECT_REFERENCE, "parent object 7777 does not exist"),
    ("parent is a DPD", _edit(DeviceElement, lambda o: replace(o, parent_id=6),
                              element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "parent object 6 is a DPD"),
    ("parent is the DVC", _edit(DeviceElement, lambda o: replace(o, parent_id=0),
                                element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "parent object 0 is a DVC"),
    ("dangling child", _edit(DeviceElement, lambda o: replace(o, children=(*o.children, 8888)),
                             element_type=ElementType.BIN), None,
     PoolError.UNKNOWN_OBJECT_REFERENCE, "child object 8888 does not exist"),
    ("child is a DVP", _edit(DeviceElement, lambda o: replace(o, children=(*o.children, 1)),
                             element_type=ElementType.BIN), None,
     PoolError.ANY_OTHER_ERROR, "child object 1 is a DVP"),
    ("child listed twice",
     _edit(DeviceElement, lambda o: replace(o, children=(*o.children, o.children[0])),
           element_type=ElementType.BIN), None, PoolError.ANY_OTHER_ERROR, "listed twice"),
    ("parent cycle", lambda objs: _cycle(objs), None, PoolError.ANY_OTHER_ERROR,
     "loops back"),
    ("presentation missing", _edit(ProcessData, lambda o: replace(o, presentation_id=5555),
                                   ddi=6), None, PoolError.UNKNOWN_OBJECT_REFERENCE,
     "presentation object 5555 does not exist"),
    ("presentation not a DVP", _edit(Property, lambda o: replace(o, presentation_id=BOOM),
                                     ddi=205), None, PoolError.ANY_OTHER_ERROR,
     "is a DET object, not a DVP"),
    ("reserved DDI", _edit(Property, lambda o: replace(o, ddi=0xFFFF), ddi=205), None,
     PoolError.ANY_OTHER_ERROR, "DDI 65535 is reserved"),
    ("reserved property bits", _edit(ProcessData, lambda o: replace(o, properties=0x09),
                                     ddi=6), None,
     PoolError.METHOD_OR_ATTRIBUTE_NOT_SUPPORTED, "properties 0x09 set reserved bits"),
    ("settable and control source", _edit(ProcessData, lambda o: replace(o, properties=0x06),
                                          ddi=6), None, PoolError.ANY_OTHER_ERROR,
     "exclude each other"),
    ("reserved trigger bits", _edit(ProcessData, lambda o: replace(o, trigger_methods=0x28),
                                    ddi=6), None,
     PoolError.METHOD_OR_ATTRIBUTE_NOT_SUPPORTED, "trigger methods 0x28"),
    ("too many decimals", _edit(ValuePresentation, lambda o: replace(o, decimals=8),
                                object_id=1), 1, PoolError.ANY_OTHER_ERROR, "8 decimals"),
    ("zero scale", _edit(ValuePresentation, lambda o: replace(o, scale=0.0), object_id=1), 1,
     PoolError.ANY_OTHER_ERROR, "not a finite non-zero"),
    ("NaN scale", _edit(ValuePresentation, lambda o: replace(o, scale=float("nan")),
                        object_id=1), 1, PoolError.ANY_OTHER_ERROR, "not a finite non-zero"),
]


def _cycle(objs: Objects) -> Objects:
    # the bin's parent becomes the first section, whose parent becomes the bin
    bin_i = _find(objs, DeviceElement, element_type=ElementType.BIN)
    sec_i = _find(objs, DeviceElement, element_type=ElementType.SECTION)
    objs[bin_i] = replace(objs[bin_i], parent_id=objs[sec_i].object_id)
    objs[sec_i] = replace(objs[sec_i], parent_id=objs[bin_i].object_id)
    return objs


def test_the_base_pool_is_valid() -> None:
    assert problems(_base()) == []
    # the object ids the cases name: DVC 0, presentations 1-3, device element 4
    assert [type(o) for o in _base()[:5]] == [Device, *[ValuePresentation] * 3, DeviceElement]


@pytest.mark.parametrize(("mutate", "object_id", "bit", "words"),
                         [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_each_rule_fires_and_names_the_object(
        mutate: Callable[[Objects], Objects], object_id: int | None, bit: PoolError,
        words: str) -> None:
    objs = mutate(_base())
    found = problems(objs)
    matching = [p for p in found if words in p.reason]
    assert matching, [str(p) for p in found]
    err = matching[0]
    assert err.pool_error == bit
    if object_id is not None:
        assert err.object_id == object_id
    if err.object_id is not None:
        assert str(err).startswith(f"DDOP object {err.object_id}: ")
    with pytest.raises(DdopError):
        check(objs)


def test_a_dpd_error_names_the_element_that_lists_it_as_parent() -> None:
    objs = _edit(ProcessData, lambda o: replace(o, presentation_id=5555), ddi=6)(_base())
    err = next(p for p in problems(objs) if "5555" in p.reason)
    bin_element = objs[_find(objs, DeviceElement, element_type=ElementType.BIN)]
    assert err.parent_id == bin_element.object_id


def test_version_3_limits_designators_to_32_bytes_and_has_no_control_source() -> None:
    objs = list(section_control_pool(sections=1, version=3).objects)
    assert problems(objs, version=3) == []
    i = _find(objs, ProcessData, ddi=6)
    objs[i] = replace(objs[i], designator="é".encode("latin-1") * 33)
    assert any("33 bytes" in p.reason for p in problems(objs, version=3))
    objs[i] = replace(objs[i], designator=b"ok", properties=0x05)
    assert any("control source property is version 4" in p.reason
               for p in problems(objs, version=3))


def test_utf8_designators_count_characters_not_bytes_in_version_4() -> None:
    objs = _base()
    i = _find(objs, ProcessData, ddi=6)
    objs[i] = replace(objs[i], designator="é".encode() * 32)  # 64 bytes, 32 characters
    assert problems(objs) == []


def test_duplicate_ids_lists_them() -> None:
    objs = [*_base(), ValuePresentation(2, 0, 1.0, 0, b"x"), ValuePresentation(3, 0, 1.0, 0,
                                                                                b"y")]
    assert duplicate_ids(objs) == [2, 3]
