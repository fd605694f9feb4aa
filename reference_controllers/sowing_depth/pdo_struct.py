"""A PDO's payload as one ``struct``, laid out from canopen's PDO map: the master's fast path.

canopen stays the source of truth for the mapping (the maps it read from the EDS, or that the
master configured by SDO): a :class:`PdoStruct` is built from a ``canopen.pdo.PdoMap``'s
variables (their offsets, lengths and data types) and only packs and unpacks the bytes.

Why: the depth controller reads its drive's statusword and position from TPDO1/TPDO2 and
writes its controlword and target velocity to RPDO2 at every SYNC. Through canopen's variables
(the map's lookup by name, ``Variable.raw`` with its debug text and ``pretty_index`` on every
read, ``decode_raw``/``encode_raw``, ``set_data`` per variable) that was ~3.5 s of a 39 s
cProfile of one depth campaign sample (150,000 TPDOs read, 76,000 RPDOs written); one
``struct`` call per frame does the same work in well under a microsecond.

Covered: maps whose variables are integers of whole bytes at whole-byte offsets, filling the
payload from its first byte without gaps. :meth:`PdoStruct.build` returns None for any other map
and the caller keeps canopen's path. A layout checks itself against canopen when it is built
(probe values, the type's extremes among them, packed and read back through the map's own
variables); on any disagreement it is not used. At run time a frame shorter than the layout,
or a value outside its data type, is left to canopen too, so errors are raised by the code
that raised them before.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from typing import Any

from canopen.objectdictionary import ODVariable
from canopen.objectdictionary.datatypes import INTEGER_TYPES, SIGNED_TYPES

__all__ = ["PdoStruct"]


class PdoStruct:
    """The payload of one PDO map as a little-endian ``struct`` of its variables in order.

    Build it with :meth:`build` (never directly): that is where it is checked.
    """

    def __init__(self, cob_id: int, names: tuple[str, ...], fmt: str,
                 ranges: tuple[tuple[int, int], ...]) -> None:
        self.cob_id = cob_id
        #: the mapped variables' names, in the map's order (the struct's fields)
        self.names = names
        self.struct = struct.Struct(fmt)
        self.size = self.struct.size
        self.ranges = ranges

    @classmethod
    def build(cls, pdo: Any) -> PdoStruct | None:
        """The layout of ``pdo`` (a canopen ``PdoMap``), or None where canopen must do it.

        None for a map that is empty, not whole bytes, not filled from byte 0 without gaps,
        or maps a variable that is not an integer, and for a layout that gives other bytes or
        values than the map's own variables on the probe values.
        """
        variables = list(pdo.map)
        if not variables:
            return None
        fmt, offset, ranges = "<", 0, []
        for var in variables:
            data_type = var.od.data_type
            packer = ODVariable.STRUCT_TYPES.get(data_type)
            if (packer is None or data_type not in INTEGER_TYPES or var.offset != offset
                    or var.length != 8 * packer.size):
                return None
            fmt += packer.format.lstrip("<>=!@")
            bits = 8 * packer.size
            ranges.append((-(1 << (bits - 1)), (1 << (bits - 1)) - 1)
                          if data_type in SIGNED_TYPES else (0, (1 << bits) - 1))
            offset += var.length
        names = tuple(var.name for var in variables)
        if len(set(names)) != len(names):
            return None                     # one object mapped twice: by name is ambiguous
        layout = cls(int(pdo.cob_id or 0), names, fmt, tuple(ranges))
        return layout if layout._agrees(pdo) else None

    def unpack(self, data: bytes | bytearray) -> tuple[int, ...] | None:
        """The mapped values of a received payload, or None if it is shorter than the map.

        Bytes past the map are ignored, as canopen's variables ignore them.
        """
        if len(data) < self.size:
            return None
        return self.struct.unpack_from(data)

    def pack(self, values: Mapping[str, int]) -> bytes | None:
        """The payload of ``values`` (name → integer for every mapped variable), or None if a
        value is not an int inside its data type (canopen raises or warns on those)."""
        return self.pack_values([values[name] for name in self.names])

    def pack_values(self, values: Sequence[int]) -> bytes | None:
        """:meth:`pack` of the values in the map's order (:attr:`names`)."""
        for value, (lo, hi) in zip(values, self.ranges, strict=True):
            if type(value) is not int or not lo <= value <= hi:
                return None
        return self.struct.pack(*values)

    def _agrees(self, pdo: Any) -> bool:
        """Whether packing and unpacking give canopen's bytes and values on probe values.

        The map's buffer is restored afterwards.
        """
        saved = bytes(pdo.data)
        try:
            limits = [_limits(var.od, lo, hi)
                      for var, (lo, hi) in zip(pdo.map, self.ranges, strict=True)]
            for k in range(4):
                values = {name: _probe(lo, hi, k)
                          for name, (lo, hi) in zip(self.names, limits, strict=True)}
                for var in pdo.map:
                    var.raw = values[var.name]
                ours = self.pack(values)
                if ours is None or bytes(pdo.data[:self.size]) != ours:
                    return False
                theirs = tuple(int(pdo[name].raw) for name in self.names)
                if self.unpack(ours) != theirs:
                    return False
            return True
        except (ValueError, KeyError, struct.error):
            return False
        finally:
            pdo.data = bytearray(saved)


def _limits(od: Any, lo: int, hi: int) -> tuple[int, int]:
    """The data type's range within the entry's EDS LowLimit/HighLimit (canopen logs a warning
    for a value outside those: the probes stay inside)."""
    if od.min is not None:
        lo = max(lo, math.ceil(od.min))
    if od.max is not None:
        hi = min(hi, math.floor(od.max))
    return lo, hi


def _probe(lo: int, hi: int, k: int) -> int:
    """Probe value ``k`` of a range: its two ends, a value with distinct bytes, its middle."""
    mixed = min(max(0x1234567890ABCDEF & hi if lo >= 0 else -(0x123456789ABCDEF & hi) // 7,
                    lo), hi)
    return (lo, hi, mixed, (lo + hi) // 2)[k]
