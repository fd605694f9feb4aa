"""The rig's DBC and its typed codecs."""

from __future__ import annotations

import can
import cantools
import pytest

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.frames import (
    DBC_PATH,
    ControllerStatus,
    DepthSetpoint,
    DrawWireFrame,
    FrameCodec,
    FrameError,
    GroundSpeed,
    InclinometerFrame,
)

FRAMES = [
    GroundSpeed(speed_mps=1.111, distance_m=180.005),
    GroundSpeed(speed_mps=0.0, distance_m=4211081.215, direction="reverse"),
    DrawWireFrame(roller_position_mm=43.2, status="ok", counter=15),
    DrawWireFrame(roller_position_mm=0.0, status="out of range", counter=0),
    InclinometerFrame(x_mv=3698, y_mv=2500, counter=7),
    InclinometerFrame(x_mv=0, y_mv=5000, x_status="below range", y_status="above range"),
    DepthSetpoint(target_depth_mm=30.0, manual_roller_position_mm=43.5, enable="on",
                  mode="automatic", counter=3),
    DepthSetpoint(target_depth_mm=0.0, enable="off", mode="constant position"),
    ControllerStatus(measured_depth_mm=29.8, roller_position_command_mm=42.75, state="controlling",
                     sensor_fault=0, drive_fault=1, speed_lost=0, counter=9),
    ControllerStatus(measured_depth_mm=-12.8, roller_position_command_mm=0.0, state="fault"),
]


@pytest.fixture(scope="module")
def codec() -> FrameCodec:
    return FrameCodec()


@pytest.mark.parametrize("frame", FRAMES, ids=lambda f: type(f).__name__)
def test_every_frame_round_trips(codec: FrameCodec, frame: object) -> None:
    msg = codec.encode(frame)  # type: ignore[arg-type]
    assert isinstance(msg, can.Message) and msg.is_extended_id and msg.dlc == 8
    assert codec.decode(msg) == frame


def test_ground_speed_is_pgn_65097_from_the_tractor_ecu(codec: FrameCodec) -> None:
    msg = codec.encode(GroundSpeed(speed_mps=1.234, distance_m=12.5))
    can_id = msg.arbitration_id
    assert can_id == 0x0CFE49F0
    assert can_id >> 26 == 3                       # priority 3
    assert (can_id >> 8) & 0x3FFFF == 65097        # PGN (EDP 0, DP 0, PF 0xFE, PS 0x49)
    assert can_id & 0xFF == 0xF0                   # tractor ECU
    # SAE J1939-71 layout: speed 0.001 m/s/bit in bytes 1-2, distance 0.001 m/bit in 3-6,
    # byte 7 reserved, byte 8 bits 1-2 direction, unused bits sent as 1.
    assert msg.data == bytes([0xD2, 0x04, 0xD4, 0x30, 0x00, 0x00, 0xFF, 0xFD])


def test_frame_ids_and_periods_match_the_rig_wiring(codec: FrameCodec) -> None:
    wiring = load_rig_config().wiring
    for frame, key in [("GBSD", "ground_speed"), ("DrawWire", "draw_wire"),
                       ("Inclinometer", "inclinometer"), ("DepthSetpoint", "depth_setpoint"),
                       ("DepthControllerStatus", "controller_status")]:
        message = codec.db.get_message_by_name(frame)
        assert message.frame_id == getattr(wiring, f"{key}_frame_id"), frame
        assert message.cycle_time == getattr(wiring, f"{key}_period_ms"), frame
    sources = {"GBSD": wiring.tractor_source_address, "DrawWire": wiring.draw_wire_source_address,
               "Inclinometer": wiring.inclinometer_source_address,
               "DepthSetpoint": wiring.terminal_source_address,
               "DepthControllerStatus": wiring.controller_source_address}
    for frame, sa in sources.items():
        assert codec.frame_id(frame) & 0xFF == sa


def test_the_dbc_is_documented(codec: FrameCodec) -> None:
    db = cantools.database.load_file(str(DBC_PATH), strict=True)
    for message in db.messages:
        assert message.comment, message.name
        assert message.protocol == "j1939"
        for signal in message.signals:
            assert signal.comment, signal.name
            assert signal.minimum is not None and signal.maximum is not None, signal.name


def test_out_of_range_values_name_the_frame_and_the_signal(codec: FrameCodec) -> None:
    with pytest.raises(FrameError, match=r"GBSD.*GBSD_GroundSpeed"):
        codec.encode(GroundSpeed(speed_mps=70.0, distance_m=0.0))
    with pytest.raises(FrameError, match=r"Inclinometer.*INC_X_Voltage"):
        codec.encode(InclinometerFrame(x_mv=5200, y_mv=0))
    with pytest.raises(FrameError, match=r"DepthSetpoint.*DS_Mode.*'cruise'"):
        codec.encode(DepthSetpoint(target_depth_mm=30.0, mode="cruise"))


def test_unknown_names_are_errors_naming_them(codec: FrameCodec) -> None:
    with pytest.raises(FrameError, match="unknown frame 'Nope'"):
        codec.encode_signals("Nope", {})
    with pytest.raises(FrameError, match="unknown signal 'DW_Speed'"):
        codec.encode_signals("DrawWire", {"DW_RollerPosition": 1.0, "DW_Status": 0,
                                          "DW_Counter": 0, "DW_Speed": 2.0})
    with pytest.raises(FrameError, match="missing signal 'DW_Status'"):
        codec.encode_signals("DrawWire", {"DW_RollerPosition": 1.0, "DW_Counter": 0})
    with pytest.raises(FrameError, match="unknown frame id 0x123"):
        codec.decode(can.Message(arbitration_id=0x123, data=bytes(8)))
    with pytest.raises(FrameError, match="DrawWire"):
        codec.decode(can.Message(arbitration_id=0x0CFF10A0, data=bytes(2), is_extended_id=True))
    with pytest.raises(FrameError, match="identifier format"):
        codec.decode(can.Message(arbitration_id=0x0CFF10A0, data=bytes(8), is_extended_id=False))
