"""Binary form of a device descriptor object pool: parse from bytes, serialise to bytes.

The layout is ISO 11783-10 annex A (little-endian integers, length-prefixed designators). The
parser checks only the form (every object complete, a known table id); the rules of the standard
(references, element numbers, designator lengths ...) are :mod:`hil.isobus.ddop.validate`'s.
Parsing then serialising gives back the same bytes for every pool the parser accepts.

Version 4 added the extended structure label to the device object, so the parser needs the
client's version (from the version message) to know whether that field is there.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

from hil.isobus.ddop.errors import DdopParseError
from hil.isobus.ddop.objects import (
    LABEL_LENGTH,
    DdopObject,
    Device,
    DeviceElement,
    ProcessData,
    Property,
    ValuePresentation,
)


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0
        self.object_id: int | None = None
        self.table = b""

    def take(self, n: int, what: str) -> bytes:
        end = self.pos + n
        if end > len(self.data):
            name = self.table.decode("latin-1")
            raise DdopParseError(
                f"{name} object ends after {len(self.data) - self.pos} of the {n} bytes of its "
                f"{what}", object_id=self.object_id, offset=self.pos)
        chunk = self.data[self.pos:end]
        self.pos = end
        return chunk

    def u8(self, what: str) -> int:
        return self.take(1, what)[0]

    def u16(self, what: str) -> int:
        return int.from_bytes(self.take(2, what), "little")

    def i32(self, what: str) -> int:
        return int.from_bytes(self.take(4, what), "little", signed=True)

    def text(self, what: str) -> bytes:
        n = self.u8(f"{what} length")
        return self.take(n, what)


def _parse_device(r: _Reader, object_id: int, version: int) -> Device:
    designator = r.text("designator")
    software_version = r.text("software version")
    name = int.from_bytes(r.take(8, "NAME"), "little")
    serial = r.text("serial number")
    structure = r.take(LABEL_LENGTH, "structure label")
    localization = r.take(LABEL_LENGTH, "localization label")
    extended = r.text("extended structure label") if version >= 4 else b""
    return Device(object_id, designator, software_version, name, serial, structure, localization,
                  extended)


def _parse_element(r: _Reader, object_id: int) -> DeviceElement:
    element_type = r.u8("element type")
    designator = r.text("designator")
    number = r.u16("element number")
    parent = r.u16("parent object id")
    count = r.u16("number of child objects")
    raw = r.take(2 * count, f"{count} child object ids")
    children = tuple(int.from_bytes(raw[i:i + 2], "little") for i in range(0, len(raw), 2))
    return DeviceElement(object_id, element_type, designator, number, parent, children)


def _parse_process_data(r: _Reader, object_id: int) -> ProcessData:
    ddi = r.u16("DDI")
    properties = r.u8("properties")
    triggers = r.u8("trigger methods")
    designator = r.text("designator")
    presentation = r.u16("presentation object id")
    return ProcessData(object_id, ddi, properties, triggers, designator, presentation)


def _parse_property(r: _Reader, object_id: int) -> Property:
    ddi = r.u16("DDI")
    value = r.i32("value")
    designator = r.text("designator")
    presentation = r.u16("presentation object id")
    return Property(object_id, ddi, value, designator, presentation)


def _parse_presentation(r: _Reader, object_id: int) -> ValuePresentation:
    offset = r.i32("offset")
    (scale,) = struct.unpack("<f", r.take(4, "scale"))
    decimals = r.u8("number of decimals")
    designator = r.text("designator")
    return ValuePresentation(object_id, offset, scale, decimals, designator)


def parse_pool(data: bytes, *, version: int = 4) -> tuple[DdopObject, ...]:
    """The objects of a binary object pool, in the order they came.

    Parameters
    ----------
    data : bytes
        The pool, without the object pool transfer command byte.
    version : int
        The client's ISO 11783-10 version (3 or 4); 4 and later carry the extended structure
        label in the device object.

    Raises
    ------
    DdopParseError
        Naming the object id (when read) and the byte offset where the form breaks.
    """
    r = _Reader(bytes(data))
    objects: list[DdopObject] = []
    while r.pos < len(r.data):
        start = r.pos
        r.object_id = None
        r.table = b"object"
        table = r.take(3, "table id")
        r.table = table
        if table not in (b"DVC", b"DET", b"DPD", b"DPT", b"DVP"):
            raise DdopParseError(f"unknown table id {table!r} (not DVC, DET, DPD, DPT or DVP)",
                                 object_id=None, offset=start)
        object_id = r.u16("object id")
        r.object_id = object_id
        if table == b"DVC":
            objects.append(_parse_device(r, object_id, version))
        elif table == b"DET":
            objects.append(_parse_element(r, object_id))
        elif table == b"DPD":
            objects.append(_parse_process_data(r, object_id))
        elif table == b"DPT":
            objects.append(_parse_property(r, object_id))
        else:
            objects.append(_parse_presentation(r, object_id))
    return tuple(objects)


def _text(value: bytes, what: str, obj: DdopObject) -> bytes:
    if len(value) > 255:
        raise DdopParseError(f"{what} of {len(value)} bytes does not fit its length byte",
                             object_id=obj.object_id)
    return bytes([len(value)]) + value


def serialise_object(obj: DdopObject, *, version: int = 4) -> bytes:
    """The binary form of one object (see :func:`serialise_pool`)."""
    head = obj.TABLE + obj.object_id.to_bytes(2, "little")
    if isinstance(obj, Device):
        for label, what in ((obj.structure_label, "structure label"),
                            (obj.localization_label, "localization label")):
            if len(label) != LABEL_LENGTH:
                raise DdopParseError(f"{what} has {len(label)} bytes, not {LABEL_LENGTH}",
                                     object_id=obj.object_id)
        body = (_text(obj.designator, "designator", obj)
                + _text(obj.software_version, "software version", obj)
                + obj.name.to_bytes(8, "little")
                + _text(obj.serial_number, "serial number", obj)
                + obj.structure_label + obj.localization_label)
        if version >= 4:
            body += _text(obj.extended_structure_label, "extended structure label", obj)
        elif obj.extended_structure_label:
            raise DdopParseError("a version 3 pool has no extended structure label",
                                 object_id=obj.object_id)
    elif isinstance(obj, DeviceElement):
        body = (bytes([obj.element_type]) + _text(obj.designator, "designator", obj)
                + obj.element_number.to_bytes(2, "little") + obj.parent_id.to_bytes(2, "little")
                + len(obj.children).to_bytes(2, "little")
                + b"".join(child.to_bytes(2, "little") for child in obj.children))
    elif isinstance(obj, ProcessData):
        body = (obj.ddi.to_bytes(2, "little") + bytes([obj.properties, obj.trigger_methods])
                + _text(obj.designator, "designator", obj)
                + obj.presentation_id.to_bytes(2, "little"))
    elif isinstance(obj, Property):
        body = (obj.ddi.to_bytes(2, "little") + obj.value.to_bytes(4, "little", signed=True)
                + _text(obj.designator, "designator", obj)
                + obj.presentation_id.to_bytes(2, "little"))
    else:
        body = (obj.offset.to_bytes(4, "little", signed=True) + struct.pack("<f", obj.scale)
                + bytes([obj.decimals]) + _text(obj.designator, "designator", obj))
    return head + body


def serialise_pool(objects: Iterable[DdopObject], *, version: int = 4) -> bytes:
    """The binary pool of ``objects`` in their order, as a client transfers it.

    Raises
    ------
    DdopParseError
        When a field does not fit its binary form (a label not 7 bytes, a designator over 255).
    OverflowError
        When an integer field does not fit its width.
    """
    return b"".join(serialise_object(obj, version=version) for obj in objects)
