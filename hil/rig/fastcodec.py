"""Precompiled bit layouts of DBC frames, derived from cantools' own message definitions.

cantools stays the source of truth: a :class:`FrameLayout` is built from a
``cantools.database.can.Message`` (start bit, length, signedness, byte order, scale, offset,
choices, minimum/maximum, unused-bit pattern) and does only the arithmetic, as plain integer
operations on one Python ``int`` per frame. It exists because a 60 s lockstep run encodes and
decodes thousands to tens of thousands of frames, and cantools' ``encode`` costs ~20 µs a frame
(dict checks, range asserts, bitstruct) where the same work with shifts and masks costs ~4 µs
(decoding: ~3 µs against ~2 µs).

Only the layouts seen on agricultural rigs are compiled: little-endian (Intel) integer signals
in a frame without multiplexing. :meth:`FrameLayout.build` returns ``None`` for anything else
(big-endian or float signals, multiplexed or container frames) and callers keep using cantools
for those. A layout also checks itself against cantools when it is built (a few probe values
per signal through both paths); on any disagreement it is not used. The rigs' tests compare the
fast path with cantools for every frame of their DBCs on random in-range values.

Callers keep their own validation rules and fall back to their cantools path whenever a value
is not a plain finite number inside the checked ranges, so errors are raised by exactly the
code that raised them before.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import cantools
from cantools.database.can import Database, Message
from cantools.database.conversion import BaseConversion, IdentityConversion, LinearConversion
from cantools.database.errors import Error as CantoolsError

from hil.errors import FrameError

__all__ = ["KIND_IDENTITY", "KIND_LINEAR", "KIND_LINEAR_INTEGER", "FrameLayout", "SignalLayout",
           "load_compiled"]

F = TypeVar("F")

#: parsed databases by (path, mtime, size, strict, frame compiler): the rig and an in-process
#: controller load the same DBC (tens of ms each with cantools' parser); only ever read
_LOADED: dict[tuple[Any, ...], tuple[Database, dict[str, Any]]] = {}


def load_compiled(path: Path, build: Callable[[Message], F | None], *,
                  strict: bool = True) -> tuple[Database, dict[str, F]]:
    """The DBC at ``path`` and what ``build`` compiles of its messages, cached.

    Cached while the file is unchanged (same path, modification time and size).

    Parameters
    ----------
    path : Path
        The DBC file.
    build : callable
        Compiles one cantools message; messages it returns None for are left out.
    strict : bool, optional
        cantools' strict loading (signals checked for overlaps and length).

    Returns
    -------
    tuple of (Database, dict)
        The cantools database and, by message name, what ``build`` returned.

    Raises
    ------
    FrameError
        The file cannot be loaded as a CAN database (naming it).
    """
    try:
        st = path.stat()
        key: tuple[Any, ...] | None = (str(path.resolve()), st.st_mtime_ns, st.st_size,
                                       strict, build)
    except OSError:
        key = None
    if key is not None and key in _LOADED:
        return _LOADED[key]
    try:
        db = cantools.database.load_file(str(path), strict=strict)
    except (OSError, CantoolsError) as exc:
        raise FrameError(f"{path}: cannot load the CAN database: {exc}") from exc
    if not isinstance(db, Database):
        raise FrameError(f"{path}: not a CAN database")
    fast: dict[str, F] = {}
    for message in db.messages:
        frame = build(message)
        if frame is not None:
            fast[message.name] = frame
    if key is not None:
        _LOADED[key] = (db, fast)
    return db, fast

#: how a signal turns a physical value into a raw one: as cantools' numeric conversion does
KIND_IDENTITY = 0          # raw = round(value)
KIND_LINEAR = 1            # raw = round((value - offset) / scale)
KIND_LINEAR_INTEGER = 2    # integer scale/offset: cantools' divmod form


@dataclass(frozen=True)
class SignalLayout:
    """One signal of a frame: where its raw bits sit and how they scale."""

    name: str
    shift: int               # start bit of an Intel signal = its shift in the frame's int
    length: int
    mask: int
    signed: bool
    raw_min: int             # what the raw field can hold
    raw_max: int
    kind: int
    scale: Any               # cantools' own objects (int or float), so the same arithmetic
    offset: Any
    minimum: float | None
    maximum: float | None
    #: raw value → choice (cantools' NamedSignalValue), or None without a value table
    choices: dict[int, Any] | None

    def to_raw(self, value: float) -> int:
        """Raw value of a finite number, as cantools' ``numeric_scaled_to_raw`` computes it."""
        if self.kind == KIND_IDENTITY:
            return round(value)
        if self.kind == KIND_LINEAR:
            return round((value - self.offset) / self.scale)
        raw = value - self.offset
        quotient, remainder = divmod(raw, self.scale)
        return round(quotient if remainder == 0 else raw / self.scale)

    def to_scaled(self, raw: int) -> int | float:
        """Physical value of a raw one, as cantools' ``raw_to_scaled`` computes it (no choices)."""
        if self.kind == KIND_IDENTITY:
            return raw
        return raw * self.scale + self.offset


@dataclass(frozen=True)
class FrameLayout:
    """The compiled layout of one cantools message."""

    name: str
    frame_id: int
    is_extended: bool
    length: int
    signals: tuple[SignalLayout, ...]
    #: bits no signal uses, ANDed with the message's unused-bit pattern (cantools' padding)
    padding: int
    #: signal names in the order cantools' ``decode`` returns them
    decode_order: tuple[str, ...]

    @classmethod
    def build(cls, message: Any) -> FrameLayout | None:
        """The layout of ``message``, or None if this module does not compile it.

        None also when the compiled form disagrees with cantools on the probe values.
        """
        if message.is_container or message.is_multiplexed():
            return None
        length = message.length
        used = 0
        signals = []
        for sig in message.signals:
            if sig.byte_order != "little_endian" or sig.conversion.is_float:
                return None
            if sig.start < 0 or sig.length < 1 or sig.start + sig.length > 8 * length:
                return None
            mask = (1 << sig.length) - 1
            if used & (mask << sig.start):
                return None                       # overlapping signals: not a plain frame
            used |= mask << sig.start
            kind = _kind(sig.conversion)
            if kind is None:
                return None
            if sig.is_signed:
                raw_min, raw_max = -(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1
            else:
                raw_min, raw_max = 0, mask
            signals.append(SignalLayout(
                name=sig.name, shift=sig.start, length=sig.length, mask=mask,
                signed=sig.is_signed, raw_min=raw_min, raw_max=raw_max, kind=kind,
                scale=sig.conversion.scale, offset=sig.conversion.offset,
                minimum=sig.minimum, maximum=sig.maximum,
                choices=dict(sig.choices) if sig.choices else None))
        pattern = int.from_bytes(bytes([message.unused_bit_pattern]) * length, "little")
        padding = ~used & ((1 << (8 * length)) - 1) & pattern
        try:
            order = tuple(message.decode(bytes(length), decode_choices=False))
        except Exception:
            return None
        layout = cls(name=message.name, frame_id=message.frame_id,
                     is_extended=message.is_extended_frame, length=length,
                     signals=tuple(signals), padding=padding, decode_order=order)
        return layout if layout._agrees_with(message) else None

    # ------------------------------------------------------------------ primitives
    def pack(self, raws: list[int], *, padding: bool) -> bytes:
        """Frame bytes from one raw value per signal (in :attr:`signals` order, in range)."""
        x = self.padding if padding else 0
        for sig, raw in zip(self.signals, raws, strict=True):
            x |= (raw & sig.mask) << sig.shift
        return x.to_bytes(self.length, "little")

    def unpack(self, data: bytes) -> list[int]:
        """Raw value of every signal (in :attr:`signals` order) from at least ``length`` bytes.

        Extra bytes are ignored, as cantools does.
        """
        x = int.from_bytes(data[:self.length], "little")
        out = []
        for sig in self.signals:
            raw = (x >> sig.shift) & sig.mask
            if sig.signed and raw > sig.raw_max:
                raw -= sig.mask + 1
            out.append(raw)
        return out

    # ------------------------------------------------------------------ self-check
    def _agrees_with(self, message: Any) -> bool:
        """Probe values through this layout and through cantools: same bytes, same values."""
        probes = [[sig.raw_min for sig in self.signals], [sig.raw_max for sig in self.signals],
                  [0 if sig.raw_min <= 0 <= sig.raw_max else sig.raw_min
                   for sig in self.signals],
                  [(sig.raw_min + sig.raw_max) // 2 for sig in self.signals],
                  [sig.raw_max - i % 3 if sig.raw_max - sig.raw_min > 3 else sig.raw_min
                   for i, sig in enumerate(self.signals)]]
        try:
            for raws in probes:
                values = {sig.name: raw for sig, raw in zip(self.signals, raws, strict=True)}
                for padding in (False, True):
                    expected = message.encode(values, scaling=False, padding=padding,
                                              strict=False)
                    if self.pack(raws, padding=padding) != expected:
                        return False
                decoded = message.decode(expected, decode_choices=False)
                mine = self.unpack(expected)
                for sig, raw in zip(self.signals, mine, strict=True):
                    if raw != values[sig.name]:
                        return False
                    scaled = sig.to_scaled(raw)
                    if type(scaled) is not type(decoded[sig.name]) \
                            or scaled != decoded[sig.name]:
                        return False
                    if math.isfinite(scaled) and sig.to_raw(scaled) != \
                            message.get_signal_by_name(sig.name).conversion \
                            .numeric_scaled_to_raw(scaled):
                        return False
        except Exception:
            return False
        return True


def _kind(conversion: Any) -> int | None:
    """Which numeric conversion cantools applies to a signal.

    The conversion itself or, for a signal with a value table, the one cantools' factory builds
    for its scale and offset.
    """
    if conversion.choices is not None:
        conversion = BaseConversion.factory(scale=conversion.scale, offset=conversion.offset,
                                            choices=None, is_float=conversion.is_float)
    if type(conversion) is IdentityConversion:
        return KIND_IDENTITY
    if type(conversion) is LinearConversion:
        return KIND_LINEAR
    if type(conversion).__name__ == "LinearIntegerConversion":
        return KIND_LINEAR_INTEGER
    return None
