"""The rules of ISO 11783-10 a device descriptor object pool must follow before a TC activates it.

:func:`problems` lists every broken rule, each a :class:`~hil.isobus.ddop.errors.DdopError`
naming the offending object (and its parent element), with the activate response's error bits;
:func:`check` raises the first. The TC refuses a pool with any problem: real terminals differ in
what they let through, so the rig is strict and says which object is wrong.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence

from hil.isobus.ddop.errors import DdopError, PoolError
from hil.isobus.ddop.objects import (
    MAX_ELEMENT_NUMBER,
    NULL_OBJECT_ID,
    DdopObject,
    Device,
    DeviceElement,
    ElementType,
    ProcessData,
    ProcessDataProperty,
    Property,
    ValuePresentation,
)

MAX_DESIGNATOR_CHARACTERS = 32
"""Designators, software version and serial number: at most 32 characters."""
MAX_DESIGNATOR_BYTES_V4 = 128
"""Version 4 designators are UTF-8: 32 characters of at most 4 bytes."""
MAX_EXTENDED_STRUCTURE_LABEL = 32
"""Bytes of the version 4 extended structure label."""
MAX_DECIMALS = 7
"""A value presentation shows 0 .. 7 decimals."""
RESERVED_DDI = 0xFFFF
_PROPERTY_BITS = 0x07
_TRIGGER_BITS = 0x1F

_UNKNOWN = PoolError.UNKNOWN_OBJECT_REFERENCE
_UNSUPPORTED = PoolError.METHOD_OR_ATTRIBUTE_NOT_SUPPORTED


def _designator_problem(value: bytes, what: str, version: int) -> str | None:
    if version >= 4:
        try:
            text = value.decode("utf-8")
        except UnicodeDecodeError as exc:
            return f"{what} is not UTF-8 ({exc.reason} at byte {exc.start})"
        if len(text) > MAX_DESIGNATOR_CHARACTERS or len(value) > MAX_DESIGNATOR_BYTES_V4:
            return (f"{what} has {len(text)} characters ({len(value)} bytes); at most "
                    f"{MAX_DESIGNATOR_CHARACTERS} characters are allowed")
        return None
    if len(value) > MAX_DESIGNATOR_CHARACTERS:
        return (f"{what} has {len(value)} bytes; a version {version} pool allows at most "
                f"{MAX_DESIGNATOR_CHARACTERS}")
    return None


def _designators(obj: DdopObject) -> list[tuple[bytes, str]]:
    if isinstance(obj, Device):
        return [(obj.designator, "designator"), (obj.software_version, "software version"),
                (obj.serial_number, "serial number")]
    return [(obj.designator, "designator")]


def problems(objects: Sequence[DdopObject], *, version: int = 4) -> list[DdopError]:
    """Every rule ``objects`` break, in pool order within each rule.

    Parameters
    ----------
    objects : sequence of DdopObject
        The pool as :func:`~hil.isobus.ddop.codec.parse_pool` returns it.
    version : int
        The client's ISO 11783-10 version: designator encoding and the control source bit.

    Returns
    -------
    list of DdopError
        Empty for a valid pool.
    """
    found: list[DdopError] = []
    by_id: dict[int, DdopObject] = {}
    parent_of: dict[int, int] = {}  # DPD/DPT id -> the element listing it

    def err(reason: str, obj: DdopObject | None, pool_error: PoolError = PoolError.ANY_OTHER_ERROR,
            parent: int | None = None) -> None:
        object_id = obj.object_id if obj is not None else None
        if parent is None and object_id is not None:
            parent = parent_of.get(object_id)
        found.append(DdopError(reason, object_id=object_id, parent_id=parent,
                               pool_error=pool_error))

    for obj in objects:
        if obj.object_id == NULL_OBJECT_ID:
            err("object id 65535 (0xFFFF) is the null object id and cannot name an object", obj)
        if obj.object_id in by_id:
            first = by_id[obj.object_id]
            err(f"duplicate object id: already used by the {first.TABLE.decode()} object before "
                f"it", obj)
        else:
            by_id[obj.object_id] = obj
        if isinstance(obj, DeviceElement):
            for child in obj.children:
                parent_of.setdefault(child, obj.object_id)

    devices = [o for o in objects if isinstance(o, Device)]
    elements = [o for o in objects if isinstance(o, DeviceElement)]
    if not devices:
        err("the pool has no device object (DVC)", None)
    for extra in devices[1:]:
        err(f"a second device object (DVC); the pool's device is object {devices[0].object_id}",
            extra)

    for obj in objects:
        for value, what in _designators(obj):
            reason = _designator_problem(value, what, version)
            if reason:
                err(reason, obj)

    for device in devices:
        if len(device.extended_structure_label) > MAX_EXTENDED_STRUCTURE_LABEL:
            err(f"extended structure label has {len(device.extended_structure_label)} bytes; at "
                f"most {MAX_EXTENDED_STRUCTURE_LABEL}", device)

    device_elements = [e for e in elements if e.element_type == ElementType.DEVICE]
    if devices and not device_elements:
        err("the pool has no device element of type 1 (device)", devices[0])
    for extra in device_elements[1:]:
        err(f"a second device element of type 1 (device); the first is object "
            f"{device_elements[0].object_id}", extra)

    numbers: dict[int, int] = {}
    for element in elements:
        if element.element_type not in {t.value for t in ElementType}:
            err(f"element type {element.element_type} is not one of 1 .. 7", element,
                _UNSUPPORTED, parent=element.parent_id)
        if element.element_number > MAX_ELEMENT_NUMBER:
            err(f"element number {element.element_number} exceeds {MAX_ELEMENT_NUMBER} (12 bits)",
                element, parent=element.parent_id)
        elif element.element_number in numbers:
            err(f"element number {element.element_number} is also element object "
                f"{numbers[element.element_number]}'s", element, parent=element.parent_id)
        else:
            numbers[element.element_number] = element.object_id
        parent = by_id.get(element.parent_id)
        if element.element_type == ElementType.DEVICE:
            if not isinstance(parent, Device):
                what = "nothing" if parent is None else f"a {parent.TABLE.decode()} object"
                err(f"the device element's parent {element.parent_id} must be the device "
                    f"object, not {what}", element,
                    _UNKNOWN if parent is None else PoolError.ANY_OTHER_ERROR,
                    parent=element.parent_id)
        elif parent is None:
            err(f"parent object {element.parent_id} does not exist", element, _UNKNOWN,
                parent=element.parent_id)
        elif not isinstance(parent, DeviceElement):
            err(f"parent object {element.parent_id} is a {parent.TABLE.decode()} object; only "
                f"the device element is the device object's child", element,
                parent=element.parent_id)
        seen: set[int] = set()
        for child_id in element.children:
            child = by_id.get(child_id)
            if child_id in seen:
                err(f"child object {child_id} is listed twice", element, parent=element.parent_id)
            seen.add(child_id)
            if child is None:
                err(f"child object {child_id} does not exist", element, _UNKNOWN,
                    parent=element.parent_id)
            elif not isinstance(child, ProcessData | Property):
                err(f"child object {child_id} is a {child.TABLE.decode()} object; children are "
                    f"DPD or DPT objects", element, parent=element.parent_id)

    # Every element must reach the device element through its parents (no cycles, no islands).
    # Each element's answer is kept, so that a chain is walked once in all, not once per
    # element on it: linear in the pool (a 6,000-element chain took seconds when it was not).
    reaches: dict[int, bool] = {}
    for element in elements:
        path: list[int] = []
        on_path: set[int] = set()
        current: DdopObject | None = element
        ok = True
        while isinstance(current, DeviceElement) and current.element_type != ElementType.DEVICE:
            if current.object_id in reaches:
                ok = reaches[current.object_id]
                break
            if current.object_id in on_path:
                ok = False
                break
            on_path.add(current.object_id)
            path.append(current.object_id)
            current = by_id.get(current.parent_id)
        for object_id in path:
            reaches[object_id] = ok
        if not ok:
            err("the element's parent chain loops back on itself", element,
                parent=element.parent_id)

    for obj in objects:
        if isinstance(obj, ProcessData | Property):
            if obj.ddi == RESERVED_DDI:
                err("DDI 65535 is reserved", obj)
            if obj.presentation_id != NULL_OBJECT_ID:
                target = by_id.get(obj.presentation_id)
                if target is None:
                    err(f"presentation object {obj.presentation_id} does not exist", obj,
                        _UNKNOWN)
                elif not isinstance(target, ValuePresentation):
                    err(f"presentation object {obj.presentation_id} is a "
                        f"{target.TABLE.decode()} object, not a DVP", obj)
        if isinstance(obj, ProcessData):
            if obj.properties & ~_PROPERTY_BITS:
                err(f"properties 0x{obj.properties:02X} set reserved bits", obj, _UNSUPPORTED)
            both = ProcessDataProperty.SETTABLE | ProcessDataProperty.CONTROL_SOURCE
            if obj.properties & ProcessDataProperty.CONTROL_SOURCE and version < 4:
                err("the control source property is version 4; the client is version "
                    f"{version}", obj, _UNSUPPORTED)
            elif obj.properties & both == both:
                err("settable and control source exclude each other", obj)
            if obj.trigger_methods & ~_TRIGGER_BITS:
                err(f"trigger methods 0x{obj.trigger_methods:02X} set reserved bits", obj,
                    _UNSUPPORTED)
        if isinstance(obj, ValuePresentation):
            if obj.decimals > MAX_DECIMALS:
                err(f"{obj.decimals} decimals; at most {MAX_DECIMALS}", obj)
            if not math.isfinite(obj.scale) or obj.scale == 0.0:
                err(f"scale {obj.scale} is not a finite non-zero number", obj)
    return found


def check(objects: Sequence[DdopObject], *, version: int = 4) -> None:
    """Raise the first of :func:`problems`, if any.

    Raises
    ------
    DdopError
        Naming the offending object, with the activate response's error bits.
    """
    found = problems(objects, version=version)
    if found:
        raise found[0]


def duplicate_ids(objects: Sequence[DdopObject]) -> list[int]:
    """Object ids used more than once (a convenience for builders and reports)."""
    return sorted(i for i, n in Counter(o.object_id for o in objects).items() if n > 1)
