"""Typed codecs for the fertilizer rig's CAN frames, through the shipped DBC (cantools).

Nothing here packs bytes by hand: every frame is encoded and decoded from ``db/fertilizer.dbc``
as cantools defines it. The hot path uses layouts compiled at start-up *from* cantools' message
and signal definitions (:mod:`hil.rig.fastcodec`: shifts and masks instead of bitstruct, ~4 µs
to encode a frame instead of ~20 µs); any frame, value or error that path does not cover goes
through cantools' own ``encode``/``decode`` as before. :class:`FertilizerDatabase` adds what a rig
needs on top:

* ``encode(name, signals)`` → :class:`can.Message` with the right id, extended flag and DLC;
  signals the DBC gives a start value (``GenSigStartValue``: reserved fields, "not available"
  codes) may be left out, any other missing, unknown or out-of-range signal raises
  :class:`FrameError` naming the frame and the signal;
* ``decode(msg)`` → ``(name, signals)``, matching ISO 11783 frames by PGN whatever their
  priority and source address;
* one helper per frame that takes the model's own report types.

Example
-------
>>> db = FertilizerDatabase()
>>> msg = db.analog_output_command(ch1_mv=2000)
>>> hex(msg.arbitration_id), bytes(msg.data).hex()
('0x220', 'd0070000')
>>> db.decode(msg)
('AnalogOutputCommand', {'Ch1Output': 2000, 'Ch2Output': 0})
>>> hex(j1939_frame_id(priority=3, pgn=65096, source_address=0xF0))
'0xcfe48f0'
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import can
from cantools.database.can import Message, Signal
from cantools.database.errors import Error as CantoolsError

from hil.errors import ConfigError, FrameError
from hil.rig.fastcodec import KIND_IDENTITY, KIND_LINEAR, FrameLayout, load_compiled
from plant_emulators.fertilizer.config import FertilizerRigConfig
from plant_emulators.fertilizer.flow_sensor import FlowReport, SensorStatus
from plant_emulators.fertilizer.ground_speed import HallReport, TractorSpeedReport

__all__ = [
    "DEFAULT_DBC",
    "FertilizerDatabase",
    "FrameError",
    "NmtCommand",
    "NmtState",
    "SignalValue",
    "j1939_frame_id",
    "j1939_pgn",
]

DEFAULT_DBC = Path(__file__).with_name("db") / "fertilizer.dbc"
"""The packaged database."""

PGN_WHEEL_BASED_SPEED = 65096
"""ISO 11783-7 Wheel-based Speed and Distance (0xFE48)."""
PGN_GROUND_BASED_SPEED = 65097
"""ISO 11783-7 Ground-based Speed and Distance (0xFE49)."""

SignalValue = int | float
"""A signal's physical value (value tables are carried as their integers)."""




class NmtState:
    """CANopen NMT states as a heartbeat carries them."""

    BOOT_UP = 0
    STOPPED = 4
    OPERATIONAL = 5
    PRE_OPERATIONAL = 127


class NmtCommand:
    """CANopen NMT command specifiers."""

    START = 1
    STOP = 2
    ENTER_PRE_OPERATIONAL = 128
    RESET_NODE = 129
    RESET_COMMUNICATION = 130


def j1939_frame_id(*, priority: int, pgn: int, source_address: int,
                   destination: int | None = None) -> int:
    """The 29-bit identifier of a J1939 / ISO 11783 frame.

    Parameters
    ----------
    priority : int
        0 (highest) .. 7.
    pgn : int
        Parameter group number (18 bits).
    source_address : int
        Sender's address, 0..253.
    destination : int, optional
        Destination address for PDU1 PGNs (PF < 240); must be omitted for PDU2.

    Returns
    -------
    int
        The identifier (without any extended-frame flag bit).
    """
    if not 0 <= priority <= 7:
        raise ValueError(f"priority must be 0..7, got {priority}")
    if not 0 <= pgn < (1 << 18):
        raise ValueError(f"pgn must be an 18-bit number, got {pgn}")
    if not 0 <= source_address <= 0xFF:
        raise ValueError(f"source_address must be 0..255, got {source_address}")
    pdu_format = (pgn >> 8) & 0xFF
    if pdu_format < 240:
        if destination is None:
            raise ValueError(f"PGN {pgn} is PDU1: a destination address is required")
        pgn = (pgn & 0x3FF00) | (destination & 0xFF)
    elif destination is not None:
        raise ValueError(f"PGN {pgn} is PDU2 (broadcast): no destination address")
    return (priority << 26) | (pgn << 8) | source_address


def j1939_pgn(frame_id: int) -> int:
    """The PGN carried by a 29-bit identifier (destination address removed for PDU1)."""
    pgn = (frame_id >> 8) & 0x3FFFF
    if ((pgn >> 8) & 0xFF) < 240:
        pgn &= 0x3FF00
    return pgn


class FertilizerDatabase:
    """The rig's CAN database with typed encoders and a decoder.

    Parameters
    ----------
    dbc_path : str or Path, optional
        The DBC file; defaults to the packaged ``db/fertilizer.dbc``.

    Raises
    ------
    FrameError
        If the file cannot be loaded.
    """

    def __init__(self, dbc_path: str | Path | None = None) -> None:
        path = Path(dbc_path) if dbc_path is not None else DEFAULT_DBC
        db, fast = _load(path)
        self.path = path
        self.db = db
        self._by_pgn: dict[int, Message] = {
            j1939_pgn(m.frame_id): m for m in db.messages if m.protocol == "j1939"}
        #: frame name → compiled encoder (frames whose layout :mod:`hil.rig.fastcodec` covers)
        self._fast: dict[str, _FastFrame] = fast
        #: (id, extended) → (message, compiled frame or None): the lookup :meth:`decode` did
        self._decode_memo: dict[tuple[int, bool], tuple[Message, _FastFrame | None]] = {}

    @classmethod
    def from_config(cls, config: FertilizerRigConfig) -> FertilizerDatabase:
        """Load the rig's database and check that its ids match ``config.wiring``.

        Raises
        ------
        hil.errors.ConfigError
            If a frame id of the DBC disagrees with a node id or address of the wiring.
        """
        db = cls(config.wiring.dbc_file)
        for key, name, expected in db._expected_ids(config):
            actual = db.frame_id(name)
            if actual != expected:
                raise ConfigError(
                    f"{db.path.name} has {name} at {actual:#x} but the wiring implies "
                    f"{expected:#x}", key=f"wiring.{key}")
        return db

    @staticmethod
    def _expected_ids(config: FertilizerRigConfig) -> list[tuple[str, str, int]]:
        w = config.wiring
        ids = [(f"flow_module_node_ids[{i}]", f"FlowModule{i + 1}", 0x180 + node)
               for i, node in enumerate(w.flow_module_node_ids)]
        ids += [
            ("ground_speed_node_id", "GroundWheelSpeed", 0x180 + w.ground_speed_node_id),
            ("dut_node_id", "ControllerStatus", 0x180 + w.dut_node_id),
            ("dut_node_id", "FertSetpoint", 0x200 + w.dut_node_id),
            ("dut_node_id", "ControllerHeartbeat", 0x700 + w.dut_node_id),
            ("analog_output_node_id", "AnalogOutputCommand",
             0x200 + w.analog_output_node_id),
            ("analog_output_node_id", "AnalogOutputHeartbeat",
             0x700 + w.analog_output_node_id),
            ("tractor_ecu_address", "WheelBasedSpeedDist",
             j1939_frame_id(priority=w.tractor_priority, pgn=PGN_WHEEL_BASED_SPEED,
                            source_address=w.tractor_ecu_address)),
            ("tractor_ecu_address", "GroundBasedSpeedDist",
             j1939_frame_id(priority=w.tractor_priority, pgn=PGN_GROUND_BASED_SPEED,
                            source_address=w.tractor_ecu_address)),
        ]
        return ids

    # ------------------------------------------------------------------ generic
    def message(self, name: str) -> Message:
        """The cantools message called ``name``."""
        try:
            return self.db.get_message_by_name(name)
        except KeyError:
            known = ", ".join(sorted(m.name for m in self.db.messages))
            raise FrameError(f"unknown frame {name!r} (known: {known})") from None

    def frame_id(self, name: str) -> int:
        """Identifier of frame ``name`` (29 bits for extended frames)."""
        return self.message(name).frame_id

    def encode(self, name: str, signals: Mapping[str, SignalValue], *,
               strict: bool = True) -> can.Message:
        """Encode frame ``name``.

        Parameters
        ----------
        name : str
            Frame (message) name in the DBC.
        signals : mapping
            Physical values by signal name. Signals with a DBC start value may be omitted.
        strict : bool, optional
            If True (default), values outside a signal's declared [min, max] are an error.
            With False they are encoded as long as the raw field can hold them (fault
            injection: a module reporting garbage).

        Returns
        -------
        can.Message
            With id, extended flag and DLC from the DBC. J1939 frames pad unused bits with 1s.

        Raises
        ------
        FrameError
            Unknown frame, unknown or missing signal, a value out of range, or a value the
            raw field cannot hold; the message names the frame and the signal.
        """
        fast = self._fast.get(name)
        if fast is not None:
            frame = fast.encode(signals, strict)
            if frame is not None:
                return frame
        return self._encode_cantools(name, signals, strict=strict)

    def _encode_cantools(self, name: str, signals: Mapping[str, SignalValue], *,
                         strict: bool) -> can.Message:
        """:meth:`encode` through cantools: every check, every error message."""
        msg = self.message(name)
        known = {s.name: s for s in msg.signals}
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
            self._check_range(name, sig, value, strict=strict)
            values[sig_name] = value
        try:
            data = msg.encode(values, strict=strict, padding=msg.protocol == "j1939")
        except (CantoolsError, ValueError, OverflowError) as exc:
            raise FrameError(f"{name}: {exc}") from exc
        return can.Message(arbitration_id=msg.frame_id, is_extended_id=msg.is_extended_frame,
                           data=data, dlc=msg.length)

    @staticmethod
    def _check_range(name: str, sig: Signal, value: SignalValue, *, strict: bool) -> None:
        if strict:
            lo, hi = sig.minimum, sig.maximum
            if (lo is not None and value < lo) or (hi is not None and value > hi):
                raise FrameError(f"{name}.{_label(sig)}: value {value!r} is outside "
                                 f"[{lo}, {hi}]")
        raw = (value - sig.offset) / sig.scale
        bits = sig.length
        raw_lo, raw_hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if sig.is_signed \
            else (0, (1 << bits) - 1)
        if not raw_lo - 0.5 <= raw <= raw_hi + 0.5:
            raise FrameError(f"{name}.{_label(sig)}: value {value!r} does not fit the "
                             f"{bits}-bit raw field")

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
        except (CantoolsError, ValueError) as exc:
            raise FrameError(f"{message.name}: cannot decode {bytes(msg.data).hex()}: {exc}") \
                from exc
        return message.name, dict(values)  # type: ignore[arg-type]

    def _lookup(self, msg: can.Message) -> Message:
        """The message a received frame is: ISO 11783 frames by PGN, others by id."""
        frame_id = msg.arbitration_id
        try:
            if msg.is_extended_id:
                return self._by_pgn.get(j1939_pgn(frame_id)) \
                    or self.db.get_message_by_frame_id(frame_id, force_extended_id=True)
            return self.db.get_message_by_frame_id(frame_id)
        except KeyError:
            kind = "extended" if msg.is_extended_id else "standard"
            raise FrameError(f"no frame with {kind} id {frame_id:#x} in {self.path.name}") \
                from None

    # ------------------------------------------------------------------ frame helpers
    def flow_module(self, row: int, report: FlowReport) -> can.Message:
        """FlowModule<row> (row from 1) from a sensor report.

        Out-of-range values (a ``garbage`` module) are encoded without the range check.
        """
        status = SensorStatus(report.status)
        valid_max = self.message(f"FlowModule{row}").get_signal_by_name("Flow").maximum or 0
        garbage = report.flow_gps > valid_max or report.grams_in_window > valid_max
        return self.encode(f"FlowModule{row}", {
            "Flow": _clip_low(report.flow_gps, 0.0),
            "WindowMass": _clip_low(report.grams_in_window, 0.0),
            "Counter": report.counter,
            "BaselineReady": int(SensorStatus.BASELINE_READY in status),
            "SlidingWindow": int(SensorStatus.SLIDING_WINDOW in status),
            "AdcOverrange": int(SensorStatus.ADC_OVERRANGE in status),
            "InterceptApplied": int(SensorStatus.INTERCEPT_APPLIED in status),
            "WindowLength": round(report.window_s * 1000.0),
        }, strict=not garbage)

    def ground_wheel_speed(self, report: HallReport, counter: int) -> can.Message:
        """GroundWheelSpeed from the Hall node's report; ``counter`` is taken modulo 256."""
        return self.encode("GroundWheelSpeed", {
            "WheelSpeed": min(report.wheel_speed_mps, 20.0),
            "PulseCount": report.pulse_count % 65536,
            "PulsePeriod": min(report.last_period_s, 6.5535),
            "Counter": counter % 256,
            "Moving": int(report.moving),
        })

    def wheel_based_speed(self, report: TractorSpeedReport) -> can.Message:
        """PGN 65096 from the tractor's wheel-based report."""
        return self.encode("WheelBasedSpeedDist", {
            "WheelBasedMachineSpeed": report.speed_mps,
            "WheelBasedMachineDistance": report.distance_m % 4211081.215,
            "MachineDirection": int(report.direction),
        })

    def ground_based_speed(self, report: TractorSpeedReport) -> can.Message:
        """PGN 65097 from the tractor's ground-based (radar) report."""
        return self.encode("GroundBasedSpeedDist", {
            "GroundBasedMachineSpeed": report.speed_mps,
            "GroundBasedMachineDistance": report.distance_m % 4211081.215,
            "MachineDirection": int(report.direction),
        })

    def setpoint(self, *, mode: int, enable: bool, target_flow_gps: float = 0.0,
                 target_rate_kg_per_hm2: float = 0.0, working_width_m: float = 0.0,
                 speed_source: int = 0, active_rows: int = 4, counter: int = 0) -> can.Message:
        """FertSetpoint, as the terminal sends it to the controller.

        ``mode``: 0 FieldRate, 1 BenchFlow, 2 ConstantSpeed. ``speed_source``: 0 Hall ground
        wheel, 1 wheel-based (PGN 65096), 2 ground-based (PGN 65097).
        """
        return self.encode("FertSetpoint", {
            "TargetRate": target_rate_kg_per_hm2,
            "WorkingWidth": working_width_m,
            "TargetFlow": target_flow_gps,
            "Mode": mode,
            "Enable": int(enable),
            "SpeedSource": speed_source,
            "ActiveRows": active_rows,
            "Counter": counter % 256,
        })

    def analog_output_command(self, *, ch1_mv: int, ch2_mv: int = 0,
                              strict: bool = True) -> can.Message:
        """AnalogOutputCommand (RPDO1 of the analog module), values in mV."""
        return self.encode("AnalogOutputCommand", {"Ch1Output": ch1_mv, "Ch2Output": ch2_mv},
                           strict=strict)

    def controller_status(self, *, target_flow_gps: float, measured_flow_gps: float,
                          command_v: float, pid_segment: int, mode: int, enabled: bool,
                          sensor_fault: bool, counter: int) -> can.Message:
        """ControllerStatus, the DUT's optional status TPDO."""
        return self.encode("ControllerStatus", {
            "TargetFlow": target_flow_gps,
            "MeasuredFlow": measured_flow_gps,
            "CommandVoltage": command_v,
            "PidSegment": pid_segment,
            "ActiveMode": mode,
            "Enabled": int(enabled),
            "SensorFault": int(sensor_fault),
            "Counter": counter % 256,
        })

    def heartbeat(self, frame: str, state: int) -> can.Message:
        """A heartbeat frame (``"ControllerHeartbeat"`` or ``"AnalogOutputHeartbeat"``)."""
        if not frame.endswith("Heartbeat"):
            raise FrameError(f"{frame!r} is not a heartbeat frame")
        return self.encode(frame, {"NmtState": state})

    def nmt(self, command: int, node_id: int = 0) -> can.Message:
        """NMT command to ``node_id`` (0 = all nodes)."""
        return self.encode("NMT", {"NmtCommand": command, "NmtTargetNode": node_id})

    def sync(self) -> can.Message:
        """A CANopen SYNC without counter."""
        return self.encode("SYNC", {})


_INF = math.inf

def _load(path: Path) -> tuple[Any, dict[str, _FastFrame]]:
    """The parsed database at ``path`` and its compiled frames (cached while unchanged)."""
    return load_compiled(path, _FastFrame.build)


class _FastFrame:
    """One frame's :meth:`FertilizerDatabase.encode` and ``decode`` on its compiled layout.

    Both return ``None`` (the caller then runs cantools) for anything but plain finite numbers
    that pass the same checks as the cantools path: unknown, missing or non-numeric signals,
    values outside [min, max] (strict) or outside the raw field, short payloads.
    """

    __slots__ = ("decode_specs", "dlc", "frame_id", "is_extended", "length", "names",
                 "padding", "specs")

    def __init__(self, message: Message, layout: FrameLayout) -> None:
        self.frame_id = message.frame_id
        self.is_extended = message.is_extended_frame
        self.dlc = message.length
        self.length = layout.length
        self.names = frozenset(s.name for s in layout.signals)
        # encode pads unused bits (with the message's unused-bit pattern) on J1939 frames only
        self.padding = layout.padding if message.protocol == "j1939" else 0
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

    def encode(self, signals: Mapping[str, SignalValue], strict: bool) -> can.Message | None:
        if not self.names.issuperset(signals):
            return None
        x = self.padding
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


def _label(sig: Signal) -> str:
    """``Name`` or ``Name [unit]`` of a cantools signal, for error messages."""
    return f"{sig.name} [{sig.unit}]" if sig.unit else sig.name


def _clip_low(value: float, low: float) -> float:
    return value if value > low else low
