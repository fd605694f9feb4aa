"""Object pool bytes to objects and back (ISO 11783-6), one layout table for both ways.

:func:`parse_objects` reads the objects of one object pool transfer (a pool may come in several
transfers; an object never spans two), :func:`serialise_object` writes one back. Only the form
is checked here (a known type, every part present, enumerated attributes in their range);
references between objects are :mod:`hil.isobus.vt.validate`'s.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any

from hil.isobus.vt.errors import NO_OBJECT, PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import INTRODUCED_IN, LAYOUTS, F, ObjectType, Var, VarKind

MacroRef = tuple[int, int]
"""(event id, macro object id) of a macro reference."""

EXTENDED_MACRO_REFERENCE = 0xFF
"""First byte of a version 5 extended macro reference (4 bytes: 0xFF, id LSB, event, id MSB)."""


@dataclass
class VtObject:
    """One object of a pool: its id, type, and attributes by the layout's names.

    ``attrs`` holds fixed attributes as ints (floats for ``scale``, ``viewport_zoom``) and the
    variable parts: ``children`` as (id, x, y) tuples, ``macros`` as (event, macro id), id
    lists, ``points`` as (x, y), strings and raw data as bytes, records as bytes each.
    ``offset`` and ``size`` say where it was in its transfer.
    """

    object_id: int
    type: ObjectType
    attrs: dict[str, Any] = field(default_factory=dict)
    offset: int = 0
    size: int = 0

    def __getitem__(self, name: str) -> Any:
        return self.attrs[name]

    def get(self, name: str, default: Any = None) -> Any:
        """An attribute, or ``default`` when the type has none of this name."""
        return self.attrs.get(name, default)

    @property
    def children(self) -> list[tuple[int, int, int]]:
        """(object id, x, y) of the children drawn inside it (empty for most types)."""
        return self.attrs.get("children", [])


# --- compiled layouts: runs of fixed attributes as one struct each ----------------------------

@dataclass(frozen=True)
class _Fixed:
    st: struct.Struct
    fields: tuple[F, ...]


_Step = _Fixed | Var


def _compile(items: tuple[F | Var, ...]) -> tuple[_Step, ...]:
    steps: list[_Step] = []
    run: list[F] = []

    def close() -> None:
        if run:
            steps.append(_Fixed(struct.Struct("<" + "".join(f.fmt for f in run)), tuple(run)))
            run.clear()

    for item in items:
        if isinstance(item, F):
            run.append(item)
        else:
            close()
            steps.append(item)
    close()
    return tuple(steps)


_STEPS: dict[int, tuple[_Step, ...]] = {int(t): _compile(v) for t, v in LAYOUTS.items()}
_H = struct.Struct("<H")
_CHILD = struct.Struct("<Hhh")
_POINT = struct.Struct("<hh")


def _truncated(object_id: int, what: str) -> VtPoolError:
    return VtPoolError(f"the transfer ends inside the object ({what})", object_id=object_id,
                       code=PoolErrorCode.ANY_OTHER)


def _check_fixed(object_id: int, otype: ObjectType, f: F, value: Any) -> None:
    if f.values is not None and value not in f.values:
        raise VtPoolError(f"{otype.name.lower()} attribute {f.name} = {value} is not one of "
                          f"{', '.join(str(v) for v in f.values)}", object_id=object_id,
                          code=PoolErrorCode.NOT_SUPPORTED)
    if f.maximum is not None and value > f.maximum:
        raise VtPoolError(f"{otype.name.lower()} attribute {f.name} = {value} is above "
                          f"{f.maximum}", object_id=object_id, code=PoolErrorCode.NOT_SUPPORTED)


def parse_objects(data: bytes, version: int = 4, *, start: int = 0) -> list[VtObject]:
    """The objects of one transfer's bytes (the pool without the 0x11 function byte).

    Raises
    ------
    VtPoolError
        Naming the first faulty object: a type unknown or not supported in ``version``, a
        truncated object, an enumerated attribute outside its values.
    """
    out: list[VtObject] = []
    pos = start
    end = len(data)
    mv = memoryview(data)
    while pos < end:
        if end - pos < 3:
            raise VtPoolError(f"{end - pos} bytes left after the last object, not an object "
                              f"(at byte {pos})", code=PoolErrorCode.ANY_OTHER)
        object_id = data[pos] | data[pos + 1] << 8
        type_code = data[pos + 2]
        steps = _STEPS.get(type_code)
        if steps is None:
            raise VtPoolError(f"unknown object type {type_code} (at byte {pos})",
                              object_id=object_id, code=PoolErrorCode.NOT_SUPPORTED)
        otype = ObjectType(type_code)
        if INTRODUCED_IN[otype] > version:
            raise VtPoolError(f"object type {type_code} ({otype.name.lower()}) needs VT "
                              f"version {INTRODUCED_IN[otype]}, the VT is version {version}",
                              object_id=object_id, code=PoolErrorCode.NOT_SUPPORTED)
        if object_id == NO_OBJECT:
            raise VtPoolError(f"object id 65535 (no object) used by a {otype.name.lower()}",
                              object_id=object_id, code=PoolErrorCode.ANY_OTHER)
        first = pos
        pos += 3
        attrs: dict[str, Any] = {}
        for step in steps:
            if isinstance(step, _Fixed):
                if pos + step.st.size > end:
                    raise _truncated(object_id, step.fields[0].name)
                values = step.st.unpack_from(data, pos)
                pos += step.st.size
                for f, value in zip(step.fields, values, strict=True):
                    if f.values is not None or f.maximum is not None:
                        _check_fixed(object_id, otype, f, value)
                    attrs[f.name] = value
                continue
            n = attrs[step.count]
            kind = step.kind
            if kind == VarKind.CHILDREN:
                stop = pos + 6 * n
                if stop > end:
                    raise _truncated(object_id, step.name)
                attrs[step.name] = [_CHILD.unpack_from(data, p) for p in range(pos, stop, 6)]
                pos = stop
            elif kind == VarKind.MACROS:
                macros: list[MacroRef] = []
                for _ in range(n):
                    if pos + 2 > end:
                        raise _truncated(object_id, "macros")
                    if data[pos] == EXTENDED_MACRO_REFERENCE and version >= 5:
                        if pos + 4 > end:
                            raise _truncated(object_id, "macros")
                        macros.append((data[pos + 2], data[pos + 1] | data[pos + 3] << 8))
                        pos += 4
                    else:
                        macros.append((data[pos], data[pos + 1]))
                        pos += 2
                attrs[step.name] = macros
            elif kind == VarKind.REFS:
                stop = pos + 2 * n
                if stop > end:
                    raise _truncated(object_id, step.name)
                attrs[step.name] = [data[p] | data[p + 1] << 8 for p in range(pos, stop, 2)]
                pos = stop
            elif kind == VarKind.BYTES:
                if pos + n > end:
                    raise _truncated(object_id, step.name)
                attrs[step.name] = bytes(mv[pos:pos + n])
                pos += n
            elif kind == VarKind.POINTS:
                stop = pos + 4 * n
                if stop > end:
                    raise _truncated(object_id, step.name)
                attrs[step.name] = [_POINT.unpack_from(data, p) for p in range(pos, stop, 4)]
                pos = stop
            elif kind == VarKind.RECORDS:
                stop = pos + step.size * n
                if stop > end:
                    raise _truncated(object_id, step.name)
                attrs[step.name] = [bytes(mv[p:p + step.size])
                                    for p in range(pos, stop, step.size)]
                pos = stop
            else:    # CODE_PLANES: plane number, number of ranges, ranges of 4 bytes
                planes: list[bytes] = []
                for _ in range(n):
                    if pos + 2 > end or pos + 2 + 4 * data[pos + 1] > end:
                        raise _truncated(object_id, "code planes")
                    size = 2 + 4 * data[pos + 1]
                    planes.append(bytes(mv[pos:pos + size]))
                    pos += size
                attrs[step.name] = planes
        out.append(VtObject(object_id, otype, attrs, first, pos - first))
    return out


def serialise_object(obj: VtObject) -> bytes:
    """The object's bytes as a pool carries them; counts are taken from the lists."""
    attrs = dict(obj.attrs)
    steps = _STEPS[int(obj.type)]
    for step in steps:      # counts follow the variable parts
        if isinstance(step, Var):
            attrs[step.count] = len(attrs.get(step.name, b"" if step.kind == VarKind.BYTES
                                              else []))
    out = bytearray(_H.pack(obj.object_id))
    out.append(int(obj.type))
    for step in steps:
        if isinstance(step, _Fixed):
            out += step.st.pack(*(attrs[f.name] for f in step.fields))
            continue
        part = attrs.get(step.name, [])
        if step.kind == VarKind.CHILDREN:
            for child in part:
                out += _CHILD.pack(*child)
        elif step.kind == VarKind.MACROS:
            for event, macro in part:
                if macro > 0xFF:
                    out += bytes([EXTENDED_MACRO_REFERENCE, macro & 0xFF, event, macro >> 8])
                else:
                    out += bytes([event, macro])
        elif step.kind == VarKind.REFS:
            for ref in part:
                out += _H.pack(ref)
        elif step.kind == VarKind.POINTS:
            for point in part:
                out += _POINT.pack(*point)
        elif step.kind == VarKind.BYTES:
            out += part
        else:
            for record in part:
                out += record
    return bytes(out)
