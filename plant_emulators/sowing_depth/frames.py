"""Typed codecs for the rig's plain CAN frames, encoded and decoded through ``sowing_depth.dbc``.

Each frame has a frozen dataclass; :class:`FrameCodec` turns one into a ``can.Message`` and back
through cantools (strict range checks, unused bits sent as 1 as J1939 wants). Nothing here packs
bytes by hand: the hot path runs on layouts compiled at start-up from cantools' own message and
signal definitions (:mod:`hil.rig.fastcodec`), with cantools' checks and value tables, and hands
anything it does not cover (and every error) to cantools' ``encode``/``decode``. Errors name the
frame and the signal.

Example
-------
>>> codec = FrameCodec()
>>> msg = codec.encode(GroundSpeed(speed_mps=1.111, distance_m=25.0))
>>> hex(msg.arbitration_id), msg.is_extended_id
('0xcfe49f0', True)
>>> codec.decode(msg)
GroundSpeed(speed_mps=1.111, distance_m=25.0, direction='forward')
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import can
from cantools.database.errors import DecodeError, EncodeError

from hil.errors import FrameError
from hil.rig.fastcodec import KIND_IDENTITY, KIND_LINEAR, FrameLayout, load_compiled

__all__ = [
    "DBC_PATH",
    "EDS_PATH",
    "ControllerStatus",
    "DepthSetpoint",
    "DrawWireFrame",
    "FrameCodec",
    "FrameError",
    "GroundSpeed",
    "InclinometerFrame",
]

_DB_DIR = Path(str(resources.files(__package__).joinpath("db")))
#: The rig's DBC (plain 29-bit frames).
DBC_PATH = _DB_DIR / "sowing_depth.dbc"
#: The servo cylinder drive's CANopen EDS.
EDS_PATH = _DB_DIR / "servo_cylinder_cia402.eds"




@dataclass(frozen=True)
class GroundSpeed:
    """PGN 65097 ground-based speed and distance from the tractor ECU."""

    FRAME: ClassVar[str] = "GBSD"
    SIGNALS: ClassVar[dict[str, str]] = {
        "speed_mps": "GBSD_GroundSpeed",
        "distance_m": "GBSD_GroundDistance",
        "direction": "GBSD_Direction",
    }
    speed_mps: float
    distance_m: float
    direction: str | int = "forward"


@dataclass(frozen=True)
class DrawWireFrame:
    """Draw-wire sensor: roller travel in mm."""

    FRAME: ClassVar[str] = "DrawWire"
    SIGNALS: ClassVar[dict[str, str]] = {
        "roller_position_mm": "DW_RollerPosition",
        "status": "DW_Status",
        "counter": "DW_Counter",
    }
    roller_position_mm: float
    status: str | int = "ok"
    counter: int = 0


@dataclass(frozen=True)
class InclinometerFrame:
    """Inclinometer outputs (X: press arm, Y: roll) in mV as read by the analog input module."""

    FRAME: ClassVar[str] = "Inclinometer"
    SIGNALS: ClassVar[dict[str, str]] = {
        "x_mv": "INC_X_Voltage",
        "y_mv": "INC_Y_Voltage",
        "x_status": "INC_X_Status",
        "y_status": "INC_Y_Status",
        "counter": "INC_Counter",
    }
    x_mv: int
    y_mv: int
    x_status: str | int = "ok"
    y_status: str | int = "ok"
    counter: int = 0


@dataclass(frozen=True)
class DepthSetpoint:
    """Depth set-point from the operator terminal."""

    FRAME: ClassVar[str] = "DepthSetpoint"
    SIGNALS: ClassVar[dict[str, str]] = {
        "target_depth_mm": "DS_TargetDepth",
        "manual_roller_position_mm": "DS_ManualRollerPosition",
        "enable": "DS_Enable",
        "mode": "DS_Mode",
        "counter": "DS_Counter",
    }
    target_depth_mm: float
    manual_roller_position_mm: float = 0.0
    enable: str | int = "on"
    mode: str | int = "automatic"
    counter: int = 0


@dataclass(frozen=True)
class ControllerStatus:
    """Status frame of the depth controller under test."""

    FRAME: ClassVar[str] = "DepthControllerStatus"
    SIGNALS: ClassVar[dict[str, str]] = {
        "measured_depth_mm": "DC_MeasuredDepth",
        "roller_position_command_mm": "DC_RollerPositionCommand",
        "state": "DC_State",
        "sensor_fault": "DC_SensorFault",
        "drive_fault": "DC_DriveFault",
        "speed_lost": "DC_SpeedLost",
        "counter": "DC_Counter",
    }
    measured_depth_mm: float
    roller_position_command_mm: float
    state: str | int = "controlling"
    sensor_fault: int = 0
    drive_fault: int = 0
    speed_lost: int = 0
    counter: int = 0


Frame = GroundSpeed | DrawWireFrame | InclinometerFrame | DepthSetpoint | ControllerStatus
_FRAME_TYPES: tuple[type[Any], ...] = (GroundSpeed, DrawWireFrame, InclinometerFrame,
                                       DepthSetpoint, ControllerStatus)


class FrameCodec:
    """Encode and decode the rig's plain frames through the DBC.

    Parameters
    ----------
    dbc_path : str or Path, optional
        The database (the packaged ``sowing_depth.dbc`` by default).
    """

    def __init__(self, dbc_path: str | Path | None = None) -> None:
        path = DBC_PATH if dbc_path is None else Path(dbc_path)
        self.db, self._fast = _load(path)
        self._by_name = {cls.FRAME: cls for cls in _FRAME_TYPES}
        for cls in _FRAME_TYPES:
            self._message(cls.FRAME)   # every typed frame must be in the database
        #: arbitration id → (message, compiled frame or None), as :meth:`decode_signals` found
        self._decode_memo: dict[int, tuple[Any, _FastFrame | None]] = {}

    def _message(self, frame: str) -> Any:
        try:
            return self.db.get_message_by_name(frame)
        except KeyError as exc:
            known = ", ".join(m.name for m in self.db.messages)
            raise FrameError(f"unknown frame {frame!r} (known: {known})") from exc

    def frame_id(self, frame: str) -> int:
        """Arbitration id of ``frame``."""
        return int(self._message(frame).frame_id)

    def encode_signals(self, frame: str, signals: Mapping[str, Any]) -> can.Message:
        """Encode raw signal values (physical units, or choice names) into a ``can.Message``.

        Raises
        ------
        FrameError
            Unknown frame, unknown or missing signal, value out of range or not a choice.
        """
        fast = self._fast.get(frame)
        if fast is not None:
            msg = fast.encode(signals)
            if msg is not None:
                return msg
        return self._encode_cantools(frame, signals)

    def _encode_cantools(self, frame: str, signals: Mapping[str, Any]) -> can.Message:
        """:meth:`encode_signals` through cantools: every check, every error message."""
        message = self._message(frame)
        known = {s.name for s in message.signals}
        unknown = sorted(set(signals) - known)
        if unknown:
            raise FrameError(f"frame {frame!r}: unknown signal {unknown[0]!r} "
                             f"(known: {', '.join(sorted(known))})")
        missing = sorted(known - set(signals))
        if missing:
            raise FrameError(f"frame {frame!r}: missing signal {missing[0]!r}")
        for signal in message.signals:
            value = signals[signal.name]
            if isinstance(value, str):
                names = [str(c) for c in (signal.choices or {}).values()]
                if value not in names:
                    raise FrameError(f"frame {frame!r}: signal {signal.name!r}: {value!r} is not "
                                     f"one of {names}")
            elif isinstance(value, bool) or not isinstance(value, int | float):
                raise FrameError(f"frame {frame!r}: signal {signal.name!r}: expected a number "
                                 f"or a choice name, got {value!r}")
        try:
            data = message.encode(dict(signals), scaling=True, padding=True, strict=True)
        except (EncodeError, KeyError, TypeError, ValueError) as exc:
            raise FrameError(f"frame {frame!r}: {exc}") from exc
        return can.Message(arbitration_id=message.frame_id, data=data,
                           is_extended_id=message.is_extended_frame)

    def decode_signals(self, msg: can.Message) -> tuple[str, dict[str, Any]]:
        """Decode ``msg`` into (frame name, signal values with choices as names)."""
        entry = self._decode_memo.get(msg.arbitration_id)
        if entry is None:
            try:
                message = self.db.get_message_by_frame_id(msg.arbitration_id)
            except KeyError as exc:
                raise FrameError(f"unknown frame id 0x{msg.arbitration_id:X}") from exc
            entry = self._decode_memo[msg.arbitration_id] = (message,
                                                             self._fast.get(message.name))
        message, fast = entry
        if fast is not None and bool(msg.is_extended_id) == fast.is_extended:
            values = fast.decode(msg.data)
            if values is not None:
                return message.name, values
        return self._decode_cantools(message, msg)

    def _decode_cantools(self, message: Any, msg: can.Message) -> tuple[str, dict[str, Any]]:
        """:meth:`decode_signals` through cantools."""
        if bool(msg.is_extended_id) != bool(message.is_extended_frame):
            raise FrameError(f"frame {message.name!r}: identifier format does not match the DBC")
        try:
            values = message.decode(bytes(msg.data), decode_choices=True, scaling=True,
                                    allow_truncated=False)
        except (DecodeError, ValueError) as exc:
            raise FrameError(f"frame {message.name!r}: {exc}") from exc
        out: dict[str, Any] = {}
        for signal in message.signals:
            value = values[signal.name]
            if isinstance(value, float):
                value = round(value, _decimals(signal.scale))
            elif not isinstance(value, int):
                value = str(value)   # a named choice
            out[signal.name] = value
        return message.name, out

    def encode(self, frame: Frame) -> can.Message:
        """Encode a typed frame."""
        cls = type(frame)
        if cls not in _FRAME_TYPES:
            raise FrameError(f"not a frame of this rig: {cls.__name__}")
        signals = {sig: getattr(frame, field) for field, sig in cls.SIGNALS.items()}
        return self.encode_signals(cls.FRAME, signals)

    def decode(self, msg: can.Message) -> Frame:
        """Decode ``msg`` into its typed frame."""
        name, values = self.decode_signals(msg)
        cls = self._by_name.get(name)
        if cls is None:
            raise FrameError(f"frame {name!r} has no typed codec")
        kwargs = {field: values[sig] for field, sig in _FIELD_SIGNALS[cls]}
        return cls(**kwargs)  # type: ignore[no-any-return]


#: per typed frame: (dataclass field, DBC signal) in field order
_FIELD_SIGNALS: dict[type[Any], tuple[tuple[str, str], ...]] = {
    cls: tuple((f.name, cls.SIGNALS[f.name]) for f in dataclasses.fields(cls))
    for cls in _FRAME_TYPES}

_INF = math.inf

def _load(path: Path) -> tuple[Any, dict[str, _FastFrame]]:
    """The parsed database at ``path`` and its compiled frames (cached while unchanged)."""
    return load_compiled(path, _FastFrame.build)


class _FastFrame:
    """One frame's :meth:`FrameCodec.encode_signals` and ``decode_signals`` on its compiled
    layout, with cantools' strict rules: choice names through the value table, numbers inside
    [min, max] widened by a millionth of the scale (raw values in the value table skip the range
    check), unused bits sent as the message's unused-bit pattern. Both return ``None`` (the
    caller then runs cantools) for anything else: unknown, missing or out-of-range signals,
    unknown choice names, booleans, non-finite numbers, short payloads.
    """

    __slots__ = ("decode_specs", "frame_id", "is_extended", "length", "names", "padding",
                 "specs")

    def __init__(self, message: Any, layout: FrameLayout) -> None:
        self.frame_id = message.frame_id
        self.is_extended = bool(message.is_extended_frame)
        self.length = layout.length
        self.names = frozenset(s.name for s in layout.signals)
        self.padding = layout.padding        # encode_signals always pads (padding=True)
        specs = []
        decode_specs = []
        for lay in layout.signals:
            sig = message.get_signal_by_name(lay.name)
            tolerance = abs(sig.conversion.scale) * 1e-6
            choices = lay.choices or {}
            specs.append((lay.name,
                          {str(text): raw for raw, text in choices.items()},   # name → raw
                          frozenset(choices),
                          -_INF if sig.minimum is None else sig.minimum - tolerance,
                          _INF if sig.maximum is None else sig.maximum + tolerance,
                          lay.kind, lay.scale, lay.offset, lay.raw_min, lay.raw_max,
                          lay.mask, lay.shift))
            decode_specs.append((lay.name, lay.shift, lay.mask,
                                 lay.raw_max if lay.signed else -1,
                                 {raw: str(text) for raw, text in choices.items()},
                                 lay.kind == KIND_IDENTITY, lay.scale, lay.offset,
                                 _decimals(sig.scale)))
        self.specs = tuple(specs)
        self.decode_specs = tuple(decode_specs)   # message.signals order, as the output is

    @classmethod
    def build(cls, message: Any) -> _FastFrame | None:
        layout = FrameLayout.build(message)
        if layout is None or any(s.kind not in (KIND_IDENTITY, KIND_LINEAR)
                                 for s in layout.signals):
            return None
        return cls(message, layout)

    def encode(self, signals: Mapping[str, Any]) -> can.Message | None:
        if len(signals) != len(self.names) or not self.names.issuperset(signals):
            return None
        x = self.padding
        for (name, by_name, table, lo, hi, kind, scale, offset, raw_lo, raw_hi, mask,
             shift) in self.specs:
            value = signals[name]
            cls = value.__class__
            if cls is str:
                raw = by_name.get(value)
                if raw is None:
                    return None
            else:
                if cls is float:
                    if not -_INF < value < _INF:
                        return None
                elif cls is not int:
                    return None               # booleans, named values, other types
                raw = round(value) if kind == KIND_IDENTITY \
                    else round((value - offset) / scale)
                if raw not in table and (value < lo or value > hi):
                    return None
            if raw < raw_lo or raw > raw_hi:
                return None
            x |= (raw & mask) << shift
        return can.Message(arbitration_id=self.frame_id, is_extended_id=self.is_extended,
                           data=x.to_bytes(self.length, "little"))

    def decode(self, data: bytes | bytearray) -> dict[str, Any] | None:
        length = self.length
        if len(data) < length:
            return None
        x = int.from_bytes(data[:length], "little")
        out: dict[str, Any] = {}
        for (name, shift, mask, signed_max, names, identity, scale, offset,
             places) in self.decode_specs:
            raw = (x >> shift) & mask
            if signed_max >= 0 and raw > signed_max:
                raw -= mask + 1
            text = names.get(raw)
            if text is not None:
                out[name] = text
            elif identity:
                out[name] = raw
            else:
                value = raw * scale + offset
                out[name] = round(value, places) if value.__class__ is float else value
        return out


def _decimals(scale: float) -> int:
    """Decimal places that represent every multiple of ``scale`` (0.001 → 3, 1 → 0)."""
    for places in range(10):
        if abs(round(scale, places) - scale) < 1e-12:
            return places
    return 10


# ------------------------------------------------------------------ the rig's bus contract
#: The rig's default binding: every quantity on its frame of the rig's own DBC.
DEFAULT_BINDING = _DB_DIR / "sowing_depth.binding.toml"

_DIRECTIONS = {0: "reverse", 1: "forward", 2: "error", 3: "not_available"}
_WIRE_STATUS = {0: "ok", 1: "out_of_range", 2: "error", 3: "not_available"}
_INC_STATUS = {0: "ok", 1: "below_range", 2: "above_range", 3: "not_available"}
_ENABLE = {0: "off", 1: "on", 2: "error", 3: "not_available"}
_MODES = {0: "manual", 1: "automatic", 2: "constant_position", 15: "not_available"}
_STATES = {0: "initialising", 1: "ready", 2: "controlling", 3: "manual", 4: "fault",
           15: "not_available"}


def _q(name: str, unit: str, direction: str, lo: float, hi: float, res: float, text: str,
       **kw: Any) -> Any:
    from hil.contract.quantity import Quantity

    return Quantity(name, unit, direction, lo, hi, res, text, **kw)  # type: ignore[arg-type]


def _quantities() -> tuple[Any, ...]:
    return (
        # the tractor ECU's ground-based speed (PGN 65097)
        _q("ground_speed", "m/s", "to_dut", 0, 20, 0.001,
           "true ground speed (PGN 65097); the controller holds the drive at standstill",
           required=True),
        _q("ground_distance", "m", "to_dut", 0, 4211081.215, 0.001, "ground distance"),
        _q("ground_direction", "", "to_dut", 0, 3, 1, "machine direction", kind="enum",
           values=_DIRECTIONS),
        # the draw-wire sensor on the press roller
        _q("roller_position", "mm", "to_dut", 0, 150, 0.01,
           "press roller travel (draw-wire sensor)", required=True),
        _q("roller_position_status", "", "to_dut", 0, 3, 1, "draw-wire sensor status",
           kind="enum", values=_WIRE_STATUS),
        _q("roller_position_counter", "", "to_dut", 0, 15, 1,
           "draw-wire sensor's rolling counter", kind="counter"),
        # the inclinometer's analog input module
        _q("inclinometer_x", "mV", "to_dut", 0, 5000, 1,
           "inclinometer X output (press arm angle, the depth)", required=True),
        _q("inclinometer_y", "mV", "to_dut", 0, 5000, 1, "inclinometer Y output (roll)"),
        _q("inclinometer_x_status", "", "to_dut", 0, 3, 1, "X channel status", kind="enum",
           values=_INC_STATUS),
        _q("inclinometer_y_status", "", "to_dut", 0, 3, 1, "Y channel status", kind="enum",
           values=_INC_STATUS),
        _q("inclinometer_counter", "", "to_dut", 0, 15, 1, "the module's rolling counter",
           kind="counter"),
        # the operator terminal
        _q("target_depth", "mm", "to_dut", 0, 150, 0.1, "depth set-point", required=True),
        _q("manual_roller_position", "mm", "to_dut", 0, 100, 0.01,
           "roller position in manual mode"),
        _q("depth_enable", "", "to_dut", 0, 3, 1, "the terminal enables depth control",
           kind="enum", values=_ENABLE, required=True),
        _q("depth_mode", "", "to_dut", 0, 15, 1, "manual / automatic / constant position",
           kind="enum", values=_MODES, required=True),
        _q("setpoint_counter", "", "to_dut", 0, 15, 1, "terminal's rolling counter",
           kind="counter"),
        # what the DUT sends: its status frame (the drive's command goes to the drive's RPDOs
        # as its EDS maps them, CiA 402: not a database signal)
        _q("dut_measured_depth", "mm", "from_dut", -100, 200, 0.1,
           "status: the depth the controller believes"),
        _q("dut_roller_position_command", "mm", "from_dut", 0, 100, 0.01,
           "status: the roller position it commands"),
        _q("dut_state", "", "from_dut", 0, 15, 1, "status: controller state", kind="enum",
           values=_STATES),
        _q("dut_sensor_fault", "", "from_dut", 0, 1, 1, "status: sensor fault", kind="flag"),
        _q("dut_drive_fault", "", "from_dut", 0, 1, 1, "status: drive fault", kind="flag"),
        _q("dut_speed_lost", "", "from_dut", 0, 1, 1, "status: ground speed lost",
           kind="flag"),
        _q("dut_status_counter", "", "from_dut", 0, 15, 1, "status: rolling counter",
           kind="counter"),
    )


def bus_contract(config: Any = None, binding_file: str = "") -> Any:
    """The sowing-depth rig's bus contract under ``config`` (default: the packaged one) with
    the binding ``binding_file`` in force (default: the rig's own)."""
    from hil.contract.quantity import CanopenNode, Contract
    from plant_emulators.sowing_depth.config import load_rig_config

    cfg = config or load_rig_config()
    w = cfg.wiring
    drive = w.drive_node_id
    node_ids = {"NMT": 0x000, "SYNC": 0x080,
                "servo drive heartbeat": 0x700 + drive, "servo drive EMCY": 0x080 + drive,
                "servo drive SDO answer": 0x580 + drive, "servo drive SDO request": 0x600 + drive,
                **{f"servo drive TPDO{n}": base + drive
                   for n, base in enumerate((0x180, 0x280, 0x380, 0x480), 1)},
                **{f"servo drive RPDO{n}": base + drive
                   for n, base in enumerate((0x200, 0x300, 0x400, 0x500), 1)}}
    return Contract(
        rig="sowing_depth", quantities=_quantities(), rows=1,
        binding_file=Path(binding_file) if binding_file else DEFAULT_BINDING,
        default_binding_file=DEFAULT_BINDING, dut_node="DepthController",
        canopen_nodes=(CanopenNode("servo drive", drive, EDS_PATH),),
        bitrate_bps=w.bitrate_bit_per_s,
        command_ids=frozenset({0x200 + drive, 0x300 + drive}),
        # the depth controller starts the drive (NMT start when its heartbeat shows it is not
        # Operational): the DBC is J1939 only, the drive is its EDS's
        dut_is_nmt_master=True, node_ids=node_ids,
        periods_ms={"ground_speed": float(w.ground_speed_period_ms),
                    "roller_position": float(w.draw_wire_period_ms),
                    "inclinometer_x": float(w.inclinometer_period_ms),
                    "target_depth": float(w.depth_setpoint_period_ms)},
        dispersion_file=Path(__file__).with_name("dispersion.toml"),
        control_period_ms=float(w.sync_period_ms), physics_period_ms=1.0)
