"""Typed codecs for the rig's plain CAN frames, encoded and decoded through ``sowing_depth.dbc``.

Each frame has a frozen dataclass; :class:`FrameCodec` turns one into a ``can.Message`` and back
through cantools (strict range checks, unused bits sent as 1 as J1939 wants). Nothing here packs
bytes by hand. Errors name the frame and the signal.

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
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import can
import cantools
from cantools.database.errors import DecodeError, EncodeError

from hil.errors import FrameError

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
        try:
            self.db = cantools.database.load_file(str(path), strict=True)
        except (OSError, cantools.database.UnsupportedDatabaseFormatError) as exc:
            raise FrameError(f"{path}: cannot load the DBC: {exc}") from exc
        self._by_name = {cls.FRAME: cls for cls in _FRAME_TYPES}
        for cls in _FRAME_TYPES:
            self._message(cls.FRAME)   # every typed frame must be in the database

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
        try:
            message = self.db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError as exc:
            raise FrameError(f"unknown frame id 0x{msg.arbitration_id:X}") from exc
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
        kwargs = {field.name: values[cls.SIGNALS[field.name]] for field in dataclasses.fields(cls)}
        return cls(**kwargs)  # type: ignore[no-any-return]


def _decimals(scale: float) -> int:
    """Decimal places that represent every multiple of ``scale`` (0.001 → 3, 1 → 0)."""
    for places in range(10):
        if abs(round(scale, places) - scale) < 1e-12:
            return places
    return 10
