"""A CAN database the rig encodes and decodes through: any file cantools reads.

:class:`BusDatabase` wraps a cantools database (DBC, KCD, ARXML or SYM) with what a rig needs:

* ``encode(name, signals)`` → :class:`can.Message` with the right id, extended flag and DLC;
  signals the database gives a start value (``GenSigStartValue``: reserved fields, "not
  available" codes) may be left out, any other missing, unknown or out-of-range signal raises
  :class:`FrameError` naming the frame and the signal; in a multiplexed message only the
  signals of the multiplexer value given are encoded;
* ``decode(msg)`` → ``(name, signals)``, matching ISO 11783 frames by PGN whatever their
  priority and source address;
* ``cycle_ms(name)``: the message's cycle time (``GenMsgCycleTime`` or the format's own).

Nothing packs bytes by hand. The hot path runs on layouts compiled at start-up *from* cantools'
message and signal definitions (:mod:`hil.rig.fastcodec`: shifts and masks instead of
bitstruct, ~4 µs to encode a frame instead of ~20 µs, each layout checked against cantools when
built); any frame, value or error that path does not cover (big-endian, float or multiplexed
signals, out-of-range values) goes through cantools' own ``encode``/``decode``.

Example
-------
>>> from plant_emulators.fertilizer.frames import DEFAULT_DBC
>>> db = BusDatabase(DEFAULT_DBC)
>>> msg = db.encode("AnalogOutputCommand", {"Ch1Output": 2000, "Ch2Output": 0})
>>> hex(msg.arbitration_id), bytes(msg.data).hex()
('0x220', 'd0070000')
>>> db.decode(msg)
('AnalogOutputCommand', {'Ch1Output': 2000, 'Ch2Output': 0})
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import can
from cantools.database.can import Message, Signal
from cantools.database.errors import Error as CantoolsError

from hil.contract.j1939 import j1939_pgn
from hil.errors import FrameError
from hil.rig.fastcodec import KIND_IDENTITY, KIND_LINEAR, FrameLayout, load_compiled

__all__ = ["BusDatabase", "Padding", "SignalValue", "signal_label"]

SignalValue = int | float
"""A signal's physical value (value tables are carried as their integers)."""

Padding = Literal["j1939", "always", "never"]
"""Which frames get their unused bits set to the database's unused-bit pattern (1s)."""


class BusDatabase:
    """A CAN database with encoders and a decoder.

    Parameters
    ----------
    path : str or Path
        The database file (``.dbc``, ``.kcd``, ``.arxml``, ``.sym``).
    padding : {"j1939", "always", "never"}, optional
        Unused bits sent as 1s on J1939 frames only (default), on every frame, or never.

    Raises
    ------
    FrameError
        If the file cannot be loaded as a CAN database (naming it).
    """

    def __init__(self, path: str | Path, *, padding: Padding = "j1939") -> None:
        path = Path(path)
        db, fast = load_compiled(path, _FastFrame.build)
        self.path = path
        self.db = db
        self.padding: Padding = padding
        self._by_pgn: dict[int, Message] = {
            j1939_pgn(m.frame_id): m for m in db.messages if m.protocol == "j1939"}
        #: frame name → compiled encoder (frames whose layout :mod:`hil.rig.fastcodec` covers)
        self._fast: dict[str, _FastFrame] = fast
        #: (id, extended) → (message, compiled frame or None): the lookup :meth:`decode` did
        self._decode_memo: dict[tuple[int, bool], tuple[Message, _FastFrame | None]] = {}

    # ------------------------------------------------------------------ lookups
    def message(self, name: str) -> Message:
        """The cantools message called ``name``."""
        try:
            return self.db.get_message_by_name(name)
        except KeyError:
            known = ", ".join(sorted(m.name for m in self.db.messages))
            raise FrameError(f"unknown frame {name!r} (known: {known})") from None

    def has_message(self, name: str) -> bool:
        """Whether the database has a message called ``name``."""
        try:
            self.db.get_message_by_name(name)
        except KeyError:
            return False
        return True

    def frame_id(self, name: str) -> int:
        """Identifier of frame ``name`` (29 bits for extended frames)."""
        return int(self.message(name).frame_id)

    def cycle_ms(self, name: str) -> float | None:
        """The cycle time the database declares for ``name`` (None: none, or 0)."""
        cycle = self.message(name).cycle_time
        return float(cycle) if cycle else None

    def _pads(self, msg: Message) -> bool:
        return self.padding == "always" or (self.padding == "j1939" and msg.protocol == "j1939")

    # ------------------------------------------------------------------ encode
    def encode(self, name: str, signals: Mapping[str, SignalValue], *,
               strict: bool = True) -> can.Message:
        """Encode frame ``name``.

        Parameters
        ----------
        name : str
            Frame (message) name in the database.
        signals : mapping
            Physical values by signal name. Signals with a start value may be omitted.
        strict : bool, optional
            If True (default), values outside a signal's declared [min, max] are an error.
            With False they are encoded as long as the raw field can hold them (fault
            injection: a module reporting garbage).

        Returns
        -------
        can.Message
            With id, extended flag and DLC from the database.

        Raises
        ------
        FrameError
            Unknown frame, unknown or missing signal, a value out of range, or a value the
            raw field cannot hold; the message names the frame and the signal.
        """
        fast = self._fast.get(name)
        if fast is not None:
            frame = fast.encode(signals, strict, self._pads(fast.message))
            if frame is not None:
                return frame
        return self._encode_cantools(name, signals, strict=strict)

    def _encode_cantools(self, name: str, signals: Mapping[str, SignalValue], *,
                         strict: bool) -> can.Message:
        """:meth:`encode` through cantools: every check, every error message."""
        msg = self.message(name)
        known = {s.name: s for s in _active_signals(msg, signals)}
        unknown = sorted(set(signals) - set(known))
        if unknown:
            raise FrameError(f"{name}: unknown signal {unknown[0]!r} "
                             f"(signals: {', '.join(known)})")
        values: dict[str, SignalValue] = {}
        for sig_name, sig in known.items():
            if sig_name in signals:
                value = signals[sig_name]
            elif sig.raw_initial is not None:
                value = sig.conversion.raw_to_scaled(sig.raw_initial, decode_choices=False)
            else:
                raise FrameError(f"{name}: missing signal {sig_name!r}")
            if not isinstance(value, int | float):
                raise FrameError(f"{name}.{sig_name}: expected a number, got {value!r}")
            if isinstance(value, float) and not math.isfinite(value):
                raise FrameError(f"{name}.{sig_name}: value {value!r} is not finite")
            _check_range(name, sig, value, strict=strict)
            values[sig_name] = value
        try:
            data = msg.encode(values, strict=strict, padding=self._pads(msg))
        except (CantoolsError, ValueError, OverflowError, KeyError) as exc:
            raise FrameError(f"{name}: {exc}") from exc
        return can.Message(arbitration_id=msg.frame_id, is_extended_id=msg.is_extended_frame,
                           data=data, dlc=msg.length)

    # ------------------------------------------------------------------ decode
    def decode(self, msg: can.Message) -> tuple[str, dict[str, SignalValue]]:
        """Decode a received frame.

        Returns
        -------
        tuple
            ``(frame name, {signal: physical value})``; value tables are returned as their
            integers.

        Raises
        ------
        FrameError
            The id is not in the database, or the data cannot be decoded.
        """
        key = (msg.arbitration_id, bool(msg.is_extended_id))
        entry = self._decode_memo.get(key)
        if entry is None:
            message = self._lookup(msg)
            entry = self._decode_memo[key] = (message, self._fast.get(message.name))
        message, fast = entry
        if fast is not None:
            values = fast.decode(msg.data)
            if values is not None:
                return message.name, values
        try:
            values = message.decode(bytes(msg.data), decode_choices=False)
        except (CantoolsError, ValueError, KeyError) as exc:
            raise FrameError(f"{message.name}: cannot decode {bytes(msg.data).hex()}: {exc}") \
                from exc
        return message.name, dict(values)  # type: ignore[arg-type]

    def lookup(self, msg: can.Message) -> Message | None:
        """The message a received frame is, or None when the database has none."""
        try:
            return self._lookup(msg)
        except FrameError:
            return None

    def _lookup(self, msg: can.Message) -> Message:
        """The message a received frame is: ISO 11783 frames by PGN, others by id."""
        frame_id = msg.arbitration_id
        try:
            if msg.is_extended_id:
                return self._by_pgn.get(j1939_pgn(frame_id)) \
                    or self.db.get_message_by_frame_id(frame_id, force_extended_id=True)
            message = self.db.get_message_by_frame_id(frame_id)
            if message.is_extended_frame:
                raise KeyError(frame_id)
            return message
        except KeyError:
            kind = "extended" if msg.is_extended_id else "standard"
            raise FrameError(f"no frame with {kind} id {frame_id:#x} in {self.path.name}") \
                from None


def _active_signals(msg: Message, signals: Mapping[str, Any]) -> list[Signal]:
    """The signals of ``msg`` encoded with ``signals``: all, or in a multiplexed message those
    of the multiplexer values given (and the multiplexers themselves)."""
    if not msg.is_multiplexed():
        return list(msg.signals)
    out = []
    for sig in msg.signals:
        ids = sig.multiplexer_ids
        if ids is None or signals.get(sig.multiplexer_signal) in ids:
            out.append(sig)
    return out


def _check_range(name: str, sig: Signal, value: SignalValue, *, strict: bool) -> None:
    if strict:
        lo, hi = sig.minimum, sig.maximum
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise FrameError(f"{name}.{signal_label(sig)}: value {value!r} is outside "
                             f"[{lo}, {hi}]")
    if sig.conversion.is_float:
        return
    raw = (value - sig.offset) / sig.scale
    bits = sig.length
    raw_lo, raw_hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if sig.is_signed \
        else (0, (1 << bits) - 1)
    if not raw_lo - 0.5 <= raw <= raw_hi + 0.5:
        raise FrameError(f"{name}.{signal_label(sig)}: value {value!r} does not fit the "
                         f"{bits}-bit raw field")


def signal_label(sig: Signal) -> str:
    """``Name`` or ``Name [unit]`` of a cantools signal, for error messages."""
    return f"{sig.name} [{sig.unit}]" if sig.unit else sig.name


_INF = math.inf


class _FastFrame:
    """One frame's :meth:`BusDatabase.encode` and ``decode`` on its compiled layout.

    Both return ``None`` (the caller then runs cantools) for anything but plain finite numbers
    that pass the same checks as the cantools path: unknown, missing or non-numeric signals,
    values outside [min, max] (strict) or outside the raw field, short payloads.
    """

    __slots__ = ("decode_specs", "dlc", "frame_id", "is_extended", "length", "message",
                 "names", "padding", "specs")

    def __init__(self, message: Message, layout: FrameLayout) -> None:
        self.message = message
        self.frame_id = message.frame_id
        self.is_extended = message.is_extended_frame
        self.dlc = message.length
        self.length = layout.length
        self.names = frozenset(s.name for s in layout.signals)
        self.padding = layout.padding
        specs = []
        for lay in layout.signals:
            sig = message.get_signal_by_name(lay.name)
            default = (sig.conversion.raw_to_scaled(sig.raw_initial, decode_choices=False)
                       if sig.raw_initial is not None else None)
            specs.append((lay.name, default,
                          -_INF if lay.minimum is None else lay.minimum,
                          _INF if lay.maximum is None else lay.maximum,
                          lay.kind, lay.scale, lay.offset, lay.raw_min, lay.raw_max,
                          lay.mask, lay.shift))
        self.specs = tuple(specs)
        by_name = {lay.name: lay for lay in layout.signals}
        self.decode_specs = tuple(
            (name, by_name[name].shift, by_name[name].mask,
             by_name[name].raw_max if by_name[name].signed else -1,
             by_name[name].kind == KIND_IDENTITY, by_name[name].scale, by_name[name].offset)
            for name in layout.decode_order)

    @classmethod
    def build(cls, message: Message) -> _FastFrame | None:
        layout = FrameLayout.build(message)
        if layout is None or any(s.kind not in (KIND_IDENTITY, KIND_LINEAR)
                                 for s in layout.signals):
            return None
        return cls(message, layout)

    def encode(self, signals: Mapping[str, SignalValue], strict: bool,
               pad: bool | None = None) -> can.Message | None:
        if not self.names.issuperset(signals):
            return None
        if pad is None:
            pad = self.message.protocol == "j1939"
        x = self.padding if pad else 0
        for (name, default, lo, hi, kind, scale, offset, raw_lo, raw_hi, mask,
             shift) in self.specs:
            value = signals.get(name, default)
            cls = value.__class__
            if cls is float:
                if not -_INF < value < _INF:
                    return None
            elif cls is not int and cls is not bool:
                return None                   # missing, or not a plain number
            if strict and (value < lo or value > hi):
                return None
            raw = round(value) if kind == KIND_IDENTITY else round((value - offset) / scale)
            if raw < raw_lo or raw > raw_hi:
                return None
            x |= (raw & mask) << shift
        return can.Message(arbitration_id=self.frame_id, is_extended_id=self.is_extended,
                           data=x.to_bytes(self.length, "little"), dlc=self.dlc)

    def decode(self, data: bytes | bytearray) -> dict[str, SignalValue] | None:
        length = self.length
        if len(data) < length:
            return None                       # cantools raises: the caller's path reports it
        x = int.from_bytes(data[:length], "little")
        out: dict[str, SignalValue] = {}
        for name, shift, mask, signed_max, identity, scale, offset in self.decode_specs:
            raw = (x >> shift) & mask
            if signed_max >= 0 and raw > signed_max:
                raw -= mask + 1
            out[name] = raw if identity else raw * scale + offset
        return out
