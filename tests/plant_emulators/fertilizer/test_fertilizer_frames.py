"""CAN database: frames round-trip, ids follow the wiring and ISO 11783, errors name things."""

from __future__ import annotations

import dataclasses

import can
import pytest

from hil.errors import ConfigError, HilError
from plant_emulators.fertilizer.flow_sensor import FlowReport, SensorStatus
from plant_emulators.fertilizer.frames import (
    FertilizerDatabase,
    FrameError,
    NmtCommand,
    NmtState,
    j1939_frame_id,
    j1939_pgn,
)
from plant_emulators.fertilizer.ground_speed import HallReport, MachineDirection, TractorSpeedReport


@pytest.fixture(scope="module")
def db() -> FertilizerDatabase:
    return FertilizerDatabase()


def _sample_value(sig):
    """A value inside the signal's declared range that is exact in its resolution."""
    lo = sig.minimum if sig.minimum is not None else 0
    hi = sig.maximum if sig.maximum is not None else lo + sig.scale
    raw = round(((lo + hi) / 2 * 0.37 + lo * 0.63 - sig.offset) / sig.scale)
    value = raw * sig.scale + sig.offset
    return min(max(value, lo), hi)


def test_every_frame_round_trips(db):
    for message in db.db.messages:
        values = {s.name: _sample_value(s) for s in message.signals}
        msg = db.encode(message.name, values)
        assert msg.arbitration_id == message.frame_id
        assert msg.is_extended_id == message.is_extended_frame
        assert msg.dlc == message.length
        name, decoded = db.decode(msg)
        assert name == message.name
        for sig in message.signals:
            assert decoded[sig.name] == pytest.approx(values[sig.name], abs=sig.scale / 2)


def test_every_frame_is_documented_with_units_and_ranges(db):
    for message in db.db.messages:
        assert message.comment, f"{message.name} has no comment"
        for sig in message.signals:
            assert sig.minimum is not None and sig.maximum is not None, sig.name
        if message.name not in ("NMT", "SYNC"):
            assert message.cycle_time, f"{message.name} has no GenMsgCycleTime"
    physical = {"Flow": "g/s", "WindowMass": "g", "WheelSpeed": "m/s", "TargetRate": "kg/hm2",
                "WorkingWidth": "m", "TargetFlow": "g/s", "Ch1Output": "mV",
                "WheelBasedMachineSpeed": "m/s", "GroundBasedMachineDistance": "m"}
    for message in db.db.messages:
        for sig in message.signals:
            if sig.name in physical:
                assert sig.unit == physical[sig.name], f"{message.name}.{sig.name}"


@pytest.mark.parametrize(("name", "pgn"), [("WheelBasedSpeedDist", 65096),
                                           ("GroundBasedSpeedDist", 65097)])
def test_isobus_ids_are_priority_pgn_and_tractor_address(db, rig_config, name, pgn):
    w = rig_config.wiring
    expected = j1939_frame_id(priority=w.tractor_priority, pgn=pgn,
                              source_address=w.tractor_ecu_address)
    assert expected == (3 << 26) | (pgn << 8) | 0xF0
    assert db.frame_id(name) == expected
    assert db.message(name).is_extended_frame
    assert db.message(name).protocol == "j1939"
    assert j1939_pgn(expected) == pgn


def test_isobus_speed_layout_and_reserved_bits(db):
    msg = db.ground_based_speed(TractorSpeedReport(2.222, 1234.567, MachineDirection.FORWARD))
    data = bytes(msg.data)
    assert int.from_bytes(data[0:2], "little") == 2222          # 0.001 m/s per bit
    assert int.from_bytes(data[2:6], "little") == 1234567       # 0.001 m per bit
    assert data[6] == 0xFF                                      # reserved
    assert data[7] == 0xFC | 0b01                               # reserved 1s, forward = 01
    wb = db.wheel_based_speed(TractorSpeedReport(1.5, 10.0, MachineDirection.FORWARD))
    assert bytes(wb.data)[6] == 255                             # max time of power: n/a
    assert bytes(wb.data)[7] & 0b11 == 0b01


def test_isobus_frames_decode_by_pgn_from_any_source_and_priority(db):
    msg = db.wheel_based_speed(TractorSpeedReport(3.0, 5.0, MachineDirection.FORWARD))
    other = can.Message(arbitration_id=j1939_frame_id(priority=6, pgn=65096,
                                                      source_address=0x80),
                        is_extended_id=True, data=msg.data)
    name, values = db.decode(other)
    assert name == "WheelBasedSpeedDist"
    assert values["WheelBasedMachineSpeed"] == pytest.approx(3.0)


def test_j1939_pdu1_needs_a_destination():
    assert j1939_frame_id(priority=6, pgn=0xEF00, source_address=0x26,
                          destination=0x10) == 0x18EF1026
    assert j1939_pgn(0x18EF1026) == 0xEF00
    with pytest.raises(ValueError, match="destination"):
        j1939_frame_id(priority=6, pgn=0xEF00, source_address=0x26)
    with pytest.raises(ValueError, match="broadcast"):
        j1939_frame_id(priority=3, pgn=65096, source_address=0xF0, destination=1)


def test_ids_follow_the_wiring(db, rig_config):
    w = rig_config.wiring
    for row, node in enumerate(w.flow_module_node_ids, 1):
        assert db.frame_id(f"FlowModule{row}") == 0x180 + node
    assert db.frame_id("GroundWheelSpeed") == 0x180 + w.ground_speed_node_id
    assert db.frame_id("ControllerHeartbeat") == 0x700 + w.dut_node_id
    assert db.frame_id("FertSetpoint") == 0x200 + w.dut_node_id
    assert db.frame_id("AnalogOutputCommand") == 0x200 + w.analog_output_node_id
    assert FertilizerDatabase.from_config(rig_config).path.name == "fertilizer.dbc"


def test_wiring_that_disagrees_with_the_dbc_is_a_config_error(rig_config):
    bad = dataclasses.replace(rig_config, wiring=dataclasses.replace(
        rig_config.wiring, ground_speed_node_id=9))
    with pytest.raises(ConfigError, match=r"\[wiring\.ground_speed_node_id\].*GroundWheelSpeed"):
        FertilizerDatabase.from_config(bad)


def test_flow_module_helper_round_trips_a_report(db):
    report = FlowReport(12.0, 34.56, 34.56, 17,
                        SensorStatus.BASELINE_READY | SensorStatus.SLIDING_WINDOW, 1.0)
    name, values = db.decode(db.flow_module(3, report))
    assert name == "FlowModule3"
    assert values["Flow"] == pytest.approx(34.56)
    assert values["WindowMass"] == pytest.approx(34.56)
    assert values["Counter"] == 17
    assert values["BaselineReady"] == 1 and values["SlidingWindow"] == 1
    assert values["AdcOverrange"] == 0 and values["WindowLength"] == 1000


def test_garbage_report_is_encoded_out_of_range(db):
    report = FlowReport(1.0, 600.0, 612.34, 3, SensorStatus.BASELINE_READY, 1.0)
    _, values = db.decode(db.flow_module(1, report))
    assert values["Flow"] == pytest.approx(612.34)
    assert values["Flow"] > db.message("FlowModule1").get_signal_by_name("Flow").maximum


def test_negative_window_mass_is_sent_as_zero(db):
    report = FlowReport(1.0, -0.2, -0.2, 3, SensorStatus.BASELINE_READY, 1.0)
    _, values = db.decode(db.flow_module(1, report))
    assert values["Flow"] == 0.0


def test_other_helpers(db):
    hall = db.ground_wheel_speed(HallReport(1.234, 70_000, 0.0412, True), counter=300)
    _, v = db.decode(hall)
    assert v["WheelSpeed"] == pytest.approx(1.234) and v["PulseCount"] == 70_000 - 65_536
    assert v["Counter"] == 44 and v["Moving"] == 1
    assert v["PulsePeriod"] == pytest.approx(0.0412)
    sp = db.setpoint(mode=0, enable=True, target_rate_kg_per_hm2=200.0, working_width_m=3.0,
                     speed_source=1)
    _, v = db.decode(sp)
    assert (v["TargetRate"], v["WorkingWidth"], v["Mode"], v["Enable"], v["ActiveRows"]) == \
        (pytest.approx(200.0), pytest.approx(3.0), 0, 1, 4)
    st = db.controller_status(target_flow_gps=23.0, measured_flow_gps=22.8, command_v=2.1,
                              pid_segment=1, mode=1, enabled=True, sensor_fault=False,
                              counter=5)
    assert db.decode(st)[1]["CommandVoltage"] == pytest.approx(2.1)
    assert db.decode(db.heartbeat("ControllerHeartbeat", NmtState.OPERATIONAL)) == \
        ("ControllerHeartbeat", {"NmtState": 5})
    assert db.decode(db.nmt(NmtCommand.START, 0x20))[1] == {"NmtCommand": 1,
                                                            "NmtTargetNode": 0x20}
    sync = db.sync()
    assert sync.arbitration_id == 0x80 and sync.dlc == 0
    out = db.analog_output_command(ch1_mv=-1, strict=False)
    assert db.decode(out)[1]["Ch1Output"] == -1


def test_unknown_frame_names_the_frame(db):
    with pytest.raises(FrameError, match="'FlowModule9'"):
        db.encode("FlowModule9", {})


def test_unknown_signal_names_frame_and_signal(db):
    with pytest.raises(FrameError, match=r"AnalogOutputCommand: unknown signal 'Ch3Output'"):
        db.encode("AnalogOutputCommand", {"Ch1Output": 1, "Ch3Output": 2})


def test_missing_signal_names_frame_and_signal(db):
    with pytest.raises(FrameError, match=r"FertSetpoint: missing signal 'TargetRate'"):
        db.encode("FertSetpoint", {"Mode": 1})


def test_out_of_range_value_names_frame_signal_and_range(db):
    with pytest.raises(FrameError, match=r"AnalogOutputCommand\.Ch1Output \[mV\]: value 12000 "
                                         r"is outside \[0, 10000\]"):
        db.analog_output_command(ch1_mv=12_000)
    with pytest.raises(FrameError, match=r"FlowModule1\.Flow \[g/s\].*16-bit raw field"):
        db.encode("FlowModule1", {"Flow": 700.0, "WindowMass": 1.0, "Counter": 0,
                                  "BaselineReady": 1, "SlidingWindow": 0, "AdcOverrange": 0,
                                  "InterceptApplied": 0}, strict=False)
    with pytest.raises(FrameError, match="not finite"):
        db.analog_output_command(ch1_mv=float("nan"))


def test_unknown_id_cannot_be_decoded(db):
    with pytest.raises(FrameError, match="standard id 0x7ff"):
        db.decode(can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"\0"))


def test_frame_errors_are_hil_errors_and_value_errors():
    assert issubclass(FrameError, HilError) and issubclass(FrameError, ValueError)


def test_missing_database_file_is_a_frame_error(tmp_path):
    with pytest.raises(FrameError, match="cannot load"):
        FertilizerDatabase(tmp_path / "none.dbc")
