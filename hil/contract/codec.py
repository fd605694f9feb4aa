"""One codec for every rig device: rig quantities in, the bound database's frames out (and back).

A device hands :meth:`ContractCodec.encode` the values of its quantities (``{"row_flow":
12.5, "row_counter": 7}``, row 2) and gets the frames that carry them under the binding in force:
one frame of the rig's own DBC, or a multiplexed frame of the DUT's database with other ids,
scalings and layouts. :meth:`ContractCodec.decode` does the reverse for the DUT's frames. What the
binding does not carry is not sent (a DUT that does not read window masses gets none); signals
of a carrying message that no quantity fills take the database's start value
(``GenSigStartValue``), else raw 0 (``hil profile check`` lists them).

The conversions are compiled once per (set of quantities, row): the hot path is a dictionary
fill and :meth:`hil.contract.database.BusDatabase.encode` (its compiled layouts). Quantities
carried as ISO 11783-10 process data (``ddi`` carriers) are not frames of a database: the Task
Controller sends them; this codec refuses to encode them (:class:`FrameError`).

Example
-------
>>> from hil.contract.registry import rig_contract
>>> codec = ContractCodec.for_contract(rig_contract("fertilizer"))
>>> [hex(m.arbitration_id) for m in codec.encode({"row_flow": 12.5, "row_counter": 3}, row=2,
...                                              strict=False)]
['0x182']
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import can

from hil.contract.binding import Binding, DdiCarrier, SignalCarrier, load_binding
from hil.contract.database import BusDatabase, Padding
from hil.contract.quantity import Contract, Quantity
from hil.contract.units import canonical, factor
from hil.errors import ConfigError, FrameError

__all__ = ["ContractCodec", "signal_unit"]

_IDENTITY, _SCALE, _MAP, _WRAP = 0, 1, 2, 3


@dataclass(frozen=True)
class _Entry:
    """One quantity on one signal: how its value becomes the signal's and back."""

    quantity: str
    row: int | None
    signal: str
    how: int
    factor: float
    to_signal: Mapping[int, int]
    to_quantity: Mapping[int, int]

    def encode(self, value: Any) -> Any:
        if self.how == _IDENTITY:
            return value
        if self.how == _SCALE:
            return value * self.factor
        if self.how == _WRAP:
            return int(value) % int(self.factor)
        raw = self.to_signal.get(int(value))
        if raw is None:
            raise FrameError(f"{self.quantity}: value {value!r} has no signal value in the "
                             f"binding's values (known: {sorted(self.to_signal)})")
        return raw

    def decode(self, value: Any) -> Any:
        if self.how == _IDENTITY:
            return value
        if self.how == _SCALE:
            return value / self.factor
        if self.how == _WRAP:
            return value
        return self.to_quantity.get(int(value), value)


@dataclass(frozen=True)
class _Frame:
    """One message to encode: its quantities, multiplexer and fill-ins."""

    message: str
    entries: tuple[_Entry, ...]
    fill: Mapping[str, Any]


def signal_unit(carrier: SignalCarrier, sig: Any) -> str | None:
    """The unit a signal's values are in: the binding's, else the database's (None: none)."""
    if carrier.unit is not None:
        return carrier.unit
    return sig.unit or None


class ContractCodec:
    """Encode rig quantities into the frames of a binding, and decode them back.

    Parameters
    ----------
    contract : Contract
        The rig's quantities (units, rows).
    binding : Binding
        Quantity → carrier.
    database : BusDatabase, optional
        The binding's database, if already loaded.
    padding : {"j1939", "always", "never"}, optional
        The database's padding rule when it is loaded here.

    Raises
    ------
    ConfigError
        A bound quantity the rig does not have, a message or signal the database lacks, or a
        unit that does not convert (naming the binding's file and key).
    """

    def __init__(self, contract: Contract, binding: Binding, database: BusDatabase | None = None,
                 *, padding: Padding = "j1939") -> None:
        self.contract = contract
        self.binding = binding
        try:
            self.db = database or BusDatabase(binding.database, padding=padding)
        except FrameError as exc:
            raise ConfigError(str(exc), path=binding.source, key="database") from exc
        self._quantities = {q.name: q for q in contract.quantities}
        self._plans: dict[tuple[tuple[str, ...], int | None], tuple[_Frame, ...]] = {}
        #: message name → its entries, for decoding (per-row and multiplexed ones resolved)
        self._by_message: dict[str, list[tuple[int | None, _Entry]]] = {}
        for name, carrier in binding.carriers.items():
            quantity = self._quantity(name)
            if isinstance(carrier, DdiCarrier):
                continue
            for row in self._rows(quantity):
                message = self._message(name, carrier, row)
                entry = self._entry(quantity, carrier, row, message)
                mux = carrier.mux_value(row)
                self._by_message.setdefault(message.name, []).append((mux, entry))

    @classmethod
    def for_contract(cls, contract: Contract, *, padding: Padding = "j1939") -> ContractCodec:
        """The codec of the contract's binding in force (its file loaded)."""
        return cls(contract, load_binding(contract.binding_file), padding=padding)

    # ------------------------------------------------------------------ setup
    def _where(self, key: str) -> dict[str, str]:
        return {"path": self.binding.source, "key": key}

    def _quantity(self, name: str) -> Quantity:
        quantity = self._quantities.get(name)
        if quantity is None:
            raise ConfigError(f"the {self.contract.rig} rig has no quantity {name!r} (see "
                              f"docs/reference/rig-quantities.md)",
                              **self._where(f"quantities.{name}"))
        return quantity

    def _rows(self, quantity: Quantity) -> list[int | None]:
        return list(range(1, self.contract.rows + 1)) if quantity.per_row else [None]

    def _message(self, name: str, carrier: SignalCarrier, row: int | None) -> Any:
        try:
            message_name = carrier.message_for(row)
            if carrier.multiplexer and row is not None and row > len(carrier.rows):
                raise ConfigError(f"{len(carrier.rows)} multiplexer values for "
                                  f"{self.contract.rows} rows")
        except ConfigError as exc:
            raise ConfigError(str(exc).split("] ", 1)[-1],
                              **self._where(f"quantities.{name}.message")) from None
        if not self.db.has_message(message_name):
            raise ConfigError(f"{self.db.path.name} has no message {message_name!r}",
                              **self._where(f"quantities.{name}.message"))
        return self.db.message(message_name)

    def _entry(self, quantity: Quantity, carrier: SignalCarrier, row: int | None,
               message: Any) -> _Entry:
        key = f"quantities.{quantity.name}"
        try:
            sig = message.get_signal_by_name(carrier.signal_for(row))
        except (KeyError, ConfigError):
            raise ConfigError(f"{message.name} has no signal {carrier.signal!r} (signals: "
                              f"{', '.join(s.name for s in message.signals)})",
                              **self._where(f"{key}.signal")) from None
        if carrier.multiplexer:
            try:
                message.get_signal_by_name(carrier.multiplexer)
            except KeyError:
                raise ConfigError(f"{message.name} has no multiplexer signal "
                                  f"{carrier.multiplexer!r}",
                                  **self._where(f"{key}.multiplexer")) from None
        if carrier.values:
            return _Entry(quantity.name, row, sig.name, _MAP, 1.0, dict(carrier.values),
                          {v: k for k, v in carrier.values.items()})
        unit = signal_unit(carrier, sig)
        if quantity.kind == "counter" and not sig.conversion.is_float:
            # a rolling counter wraps at the signal's width (a 4-bit alive counter, say)
            modulus = (1 << sig.length) if not sig.is_signed else (1 << (sig.length - 1))
            if modulus <= quantity.maximum:
                return _Entry(quantity.name, row, sig.name, _WRAP, float(modulus), {}, {})
        if quantity.kind in ("flag", "enum", "counter") and unit is None:
            return _Entry(quantity.name, row, sig.name, _IDENTITY, 1.0, {}, {})
        try:
            f = factor(quantity.unit, unit)
        except ConfigError as exc:
            hint = "" if carrier.unit else " (the database's unit; set unit = ... if it is wrong)"
            raise ConfigError(f"{sig.name}: {str(exc).split('] ', 1)[-1]}{hint}",
                              **self._where(f"{key}.unit")) from None
        if f == 1.0:
            return _Entry(quantity.name, row, sig.name, _IDENTITY, 1.0, {}, {})
        return _Entry(quantity.name, row, sig.name, _SCALE, f, {}, {})

    def _plan(self, names: tuple[str, ...], row: int | None) -> tuple[_Frame, ...]:
        frames: dict[str, tuple[list[_Entry], dict[str, Any]]] = {}
        for name in names:
            carrier = self.binding.carriers.get(name)
            if carrier is None:
                if name not in self._quantities:
                    raise FrameError(f"the {self.contract.rig} rig has no quantity {name!r}")
                continue                       # not bound: the DUT does not take it
            if isinstance(carrier, DdiCarrier):
                raise FrameError(f"{name} is bound to ISO 11783-10 process data "
                                 f"({carrier.describe()}): the Task Controller sends it")
            quantity = self._quantities[name]
            q_row = row if quantity.per_row else None
            message = carrier.message_for(q_row)
            entry = next(e for mux, e in self._by_message[message]
                         if e.quantity == name and e.row == q_row)
            entries, fill = frames.setdefault(message, ([], {}))
            entries.append(entry)
            mux = carrier.mux_value(q_row)
            if mux is not None:
                fill[carrier.multiplexer] = mux
        plan = []
        for message, (entries, fill) in frames.items():
            msg = self.db.message(message)
            bound = {e.signal for e in entries} | set(fill)
            for sig in msg.signals:
                if sig.name in bound or sig.raw_initial is not None:
                    continue
                if sig.multiplexer_ids is not None and \
                        fill.get(sig.multiplexer_signal) not in sig.multiplexer_ids:
                    continue
                fill[sig.name] = _zero(sig)
            plan.append(_Frame(message, tuple(entries), fill))
        return tuple(plan)

    # ------------------------------------------------------------------ use
    def encode(self, values: Mapping[str, Any], *, row: int | None = None,
               strict: bool = True) -> list[can.Message]:
        """The frames carrying ``values`` (quantity name → value in the quantity's unit).

        Parameters
        ----------
        values : mapping
            The quantities of one device's report; those the binding does not carry are
            left out.
        row : int, optional
            The row (from 1) of the per-row quantities among them.
        strict : bool, optional
            False encodes values outside a signal's declared range (a module reporting
            garbage) as long as the raw field holds them.

        Returns
        -------
        list of can.Message
            One per carrying message, in the order the quantities first name them.

        Raises
        ------
        FrameError
            A value the carrier cannot hold, an unknown quantity (naming it).
        """
        key = (tuple(values), row)
        plan = self._plans.get(key)
        if plan is None:
            plan = self._plans[key] = self._plan(key[0], row)
        out = []
        for frame in plan:
            signals = dict(frame.fill)
            for entry in frame.entries:
                signals[entry.signal] = entry.encode(values[entry.quantity])
            out.append(self.db.encode(frame.message, signals, strict=strict))
        return out

    def decode(self, msg: can.Message) -> dict[str, Any] | None:
        """The quantities a received frame carries (``name`` or ``name[row]`` → value).

        Returns
        -------
        dict or None
            None when the frame carries no bound quantity.

        Raises
        ------
        FrameError
            The frame is in the database but its data cannot be decoded.
        """
        message = self.db.lookup(msg)
        if message is None or message.name not in self._by_message:
            return None
        _, signals = self.db.decode(msg)
        out: dict[str, Any] = {}
        for mux, entry in self._by_message[message.name]:
            if mux is not None:
                carrier = self.binding.carriers[entry.quantity]
                assert isinstance(carrier, SignalCarrier)
                if signals.get(carrier.multiplexer) != mux:
                    continue
            if entry.signal in signals:
                name = self._quantities[entry.quantity].row_name(entry.row)
                out[name] = entry.decode(signals[entry.signal])
        return out

    def frame_id(self, quantity: str, row: int | None = None) -> int:
        """The id of the frame that carries ``quantity`` (of ``row``).

        Raises
        ------
        KeyError
            The binding does not carry it on a database frame.
        """
        carrier = self.binding.carriers.get(quantity)
        if not isinstance(carrier, SignalCarrier):
            raise KeyError(f"{quantity} is not carried by a frame of {self.db.path.name}")
        return self.db.frame_id(carrier.message_for(row if
                                                    self._quantities[quantity].per_row
                                                    else None))

    def carries(self, quantity: str) -> bool:
        """Whether the binding carries ``quantity`` on a database frame."""
        return isinstance(self.binding.carriers.get(quantity), SignalCarrier)

    def cycle_ms(self, quantity: str, row: int | None = None) -> float | None:
        """The cycle time of ``quantity``'s frame: the binding's, the database's or the rig's."""
        carrier = self.binding.carriers.get(quantity)
        if isinstance(carrier, SignalCarrier):
            if carrier.cycle_ms is not None:
                return carrier.cycle_ms
            per_row = self._quantities[quantity].per_row
            cycle = self.db.cycle_ms(carrier.message_for((row or 1) if per_row else None))
            if cycle is not None:
                return cycle
        return self.contract.periods_ms.get(quantity)

    def period_s(self, quantity: str, default_s: float) -> float:
        """:meth:`cycle_ms` in seconds, else ``default_s`` (a device's period)."""
        cycle = self.cycle_ms(quantity)
        return cycle / 1000.0 if cycle is not None else default_s



def _zero(sig: Any) -> Any:
    """The physical value of raw 0, or the signal's minimum when raw 0 is below it."""
    value = sig.conversion.raw_to_scaled(0, decode_choices=False)
    if sig.minimum is not None and value < sig.minimum:
        return sig.minimum
    if sig.maximum is not None and value > sig.maximum:
        return sig.maximum
    return value


def unit_of(quantity: Quantity) -> str:
    """The quantity's unit as the unit table spells it."""
    return canonical(quantity.unit)
