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

from pathlib import Path
from typing import Any

import can

from hil.contract.database import BusDatabase, SignalValue
from hil.contract.j1939 import j1939_frame_id, j1939_pgn
from hil.contract.quantity import CanopenNode, Contract, Quantity
from hil.errors import ConfigError, FrameError
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowReport, SensorStatus
from plant_emulators.fertilizer.ground_speed import HallReport, TractorSpeedReport

__all__ = [
    "DEFAULT_BINDING",
    "DEFAULT_DBC",
    "QUANTITIES",
    "FertilizerDatabase",
    "FrameError",
    "NmtCommand",
    "NmtState",
    "SignalValue",
    "bus_contract",
    "j1939_frame_id",
    "j1939_pgn",
]

DEFAULT_DBC = Path(__file__).with_name("db") / "fertilizer.dbc"
"""The packaged database."""
DEFAULT_BINDING = Path(__file__).with_name("db") / "fertilizer.binding.toml"
"""The packaged database's binding of the rig quantities (the rig's default binding)."""

PGN_WHEEL_BASED_SPEED = 65096
"""ISO 11783-7 Wheel-based Speed and Distance (0xFE48)."""
PGN_GROUND_BASED_SPEED = 65097
"""ISO 11783-7 Ground-based Speed and Distance (0xFE49)."""


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


class FertilizerDatabase(BusDatabase):
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
        super().__init__(Path(dbc_path) if dbc_path is not None else DEFAULT_DBC,
                         padding="j1939")

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
            ("dut_node_id", "MeterCalibration", 0x300 + w.dut_node_id),
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


def _clip_low(value: float, low: float) -> float:
    return value if value > low else low


# ------------------------------------------------------------------ the rig's bus contract
_FLOW_MODES = {0: "field_rate", 1: "bench_flow", 2: "constant_speed"}
_SPEED_SOURCES = {0: "hall_ground_wheel", 1: "wheel_based", 2: "ground_based"}
_DIRECTIONS = {0: "reverse", 1: "forward", 2: "error", 3: "not_available"}
_NMT_STATES = {0: "boot_up", 4: "stopped", 5: "operational", 127: "pre_operational"}
_PID_SEGMENTS = {0: "none", 1: "fine", 2: "medium", 3: "coarse"}


def _q(name: str, unit: str, direction: str, lo: float, hi: float, res: float, text: str,
       **kw: Any) -> Quantity:
    return Quantity(name, unit, direction, lo, hi, res, text, **kw)  # type: ignore[arg-type]


QUANTITIES: tuple[Quantity, ...] = (
    # the terminal's set-points (FertSetpoint in the rig's DBC)
    _q("target_rate", "kg/hm2", "to_dut", 0, 1000, 0.1,
       "field target application rate M of [F] eq. (1)"),
    _q("working_width", "m", "to_dut", 0, 30, 0.001, "field working width D of [F] eq. (1)"),
    _q("target_flow", "g/s", "to_dut", 0, 250, 0.01,
       "bench target flow per row (and the flow a constant-speed run is calibrated for)",
       required=True),
    _q("mode", "", "to_dut", 0, 3, 1, "what the controller does", kind="enum",
       values=_FLOW_MODES, required=True),
    _q("enable", "", "to_dut", 0, 1, 1, "the terminal enables metering (0: command 0 V)",
       kind="flag", required=True),
    _q("speed_source", "", "to_dut", 0, 3, 1, "the ground speed a field run uses",
       kind="enum", values=_SPEED_SOURCES),
    _q("active_rows", "rows", "to_dut", 1, 7, 1, "rows sharing the total target flow"),
    _q("setpoint_counter", "", "to_dut", 0, 255, 1, "rolling counter of the set-points",
       kind="counter"),
    # the operator's calibration test of the lot (MeterCalibration; optional: sent only when
    # the run's lot is not the one the controllers' own calibration was made on)
    _q("calibration_grams_per_rev", "g/rev", "to_dut", 0, 655.35, 0.01,
       "the operator's calibration test: weighed grams per meter-shaft revolution and row "
       "at calibration_shaft_speed"),
    _q("calibration_shaft_speed", "r/min", "to_dut", 0, 100, 0.01,
       "meter shaft speed of the calibration test"),
    _q("calibration_revolutions", "", "to_dut", 0, 65535, 1,
       "shaft revolutions the calibration test counted"),

    # each row's flow detection module (FlowModule<row>)
    _q("row_flow", "g/s", "to_dut", 0, 250, 0.01,
       "the row's sensed flow: mean over the module's window", per_row=True, required=True,
       event_driven=True),
    _q("row_window_mass", "g", "to_dut", 0, 250, 0.01, "grams that passed during the window",
       per_row=True, event_driven=True),
    _q("row_counter", "", "to_dut", 0, 255, 1, "the module's rolling report counter",
       per_row=True, kind="counter", event_driven=True),
    _q("row_baseline_ready", "", "to_dut", 0, 1, 1,
       "the empty-pipe baseline is acquired: values are valid", per_row=True, kind="flag",
       event_driven=True),
    _q("row_sliding_window", "", "to_dut", 0, 1, 1, "the window slides (10 Hz reports)",
       per_row=True, kind="flag", event_driven=True),
    _q("row_adc_overrange", "", "to_dut", 0, 1, 1,
       "a conversion in the window was out of the AD7746's range", per_row=True, kind="flag",
       event_driven=True),
    _q("row_intercept_applied", "", "to_dut", 0, 1, 1,
       "the calibration intercept was added to the window", per_row=True, kind="flag",
       event_driven=True),
    _q("row_window_length", "ms", "to_dut", 0, 10000, 1,
       "length of the window the values cover", per_row=True, event_driven=True),
    # the Hall ground-wheel node (GroundWheelSpeed)
    _q("wheel_speed", "m/s", "to_dut", 0, 20, 0.001,
       "ground-wheel surface speed (includes its slip)"),
    _q("wheel_pulse_count", "pulses", "to_dut", 0, 65535, 1, "pulses since power-up",
       kind="counter"),
    _q("wheel_pulse_period", "s", "to_dut", 0, 6.5535, 0.0001, "time between the last pulses"),
    _q("wheel_counter", "", "to_dut", 0, 255, 1, "rolling counter of the node's frames",
       kind="counter"),
    _q("wheel_moving", "", "to_dut", 0, 1, 1, "a pulse came within the last second",
       kind="flag"),
    # the tractor ECU (ISO 11783-7 PGN 65096 / 65097)
    _q("wheel_based_speed", "m/s", "to_dut", 0, 20, 0.001,
       "tractor wheel-based speed (PGN 65096; includes drive-wheel slip)"),
    _q("wheel_based_distance", "m", "to_dut", 0, 4211081.215, 0.001,
       "tractor wheel-based distance (PGN 65096)"),
    _q("wheel_based_direction", "", "to_dut", 0, 3, 1, "machine direction (PGN 65096)",
       kind="enum", values=_DIRECTIONS),
    _q("ground_based_speed", "m/s", "to_dut", 0, 20, 0.001,
       "tractor ground-based (radar) speed (PGN 65097)"),
    _q("ground_based_distance", "m", "to_dut", 0, 4211081.215, 0.001,
       "tractor ground-based distance (PGN 65097)"),
    _q("ground_based_direction", "", "to_dut", 0, 3, 1, "machine direction (PGN 65097)",
       kind="enum", values=_DIRECTIONS),
    # what the DUT sends
    _q("motor_command", "mV", "from_dut", 0, 10000, 1,
       "the motor's speed command on the analog output module's channel (its RPDO1, "
       "0x6411): 0-10 V = 0-3000 rpm", required=True),
    _q("dut_nmt_state", "", "from_dut", 0, 127, 1,
       "the DUT's CANopen heartbeat (0x700 + node id), consumed by the analog module",
       kind="enum", values=_NMT_STATES),
    _q("dut_target_flow", "g/s", "from_dut", 0, 250, 0.01,
       "status: the per-row target the DUT holds (recorded, never judged)"),
    _q("dut_measured_flow", "g/s", "from_dut", 0, 250, 0.01,
       "status: the per-row flow the DUT believes"),
    _q("dut_command_voltage", "V", "from_dut", 0, 10, 0.001,
       "status: the command the DUT wrote"),
    _q("dut_pid_segment", "", "from_dut", 0, 3, 1, "status: piecewise PID segment",
       kind="enum", values=_PID_SEGMENTS),
    _q("dut_mode", "", "from_dut", 0, 3, 1, "status: the mode the DUT executes", kind="enum",
       values=_FLOW_MODES),
    _q("dut_enabled", "", "from_dut", 0, 1, 1, "status: metering enabled", kind="flag"),
    _q("dut_sensor_fault", "", "from_dut", 0, 1, 1,
       "status: the DUT detected a stale, silent or implausible flow module", kind="flag"),
    _q("dut_status_counter", "", "from_dut", 0, 255, 1, "status: rolling counter",
       kind="counter"),
)
"""Every quantity the fertilizer rig's devices publish to the DUT or take from it."""


def bus_contract(config: FertilizerRigConfig | None = None) -> Contract:
    """The fertilizer rig's bus contract under ``config`` (default: the packaged one).

    The binding in force is ``wiring.binding_file`` (the rig's default binding of its own DBC
    unless a DUT profile binds its database).
    """
    cfg = config or load_rig_config()
    w = cfg.wiring
    analog = w.analog_output_node_id
    node_ids = {"NMT": 0x000, "SYNC": 0x080,
                "analog output module heartbeat": 0x700 + analog,
                "analog output module EMCY": 0x080 + analog,
                "analog output module SDO answer": 0x580 + analog,
                "analog output module SDO request": 0x600 + analog,
                "ground wheel node heartbeat": 0x700 + w.ground_speed_node_id,
                **{f"flow module {i + 1} heartbeat": 0x700 + node
                   for i, node in enumerate(w.flow_module_node_ids)}}
    sensor = cfg.flow_sensor
    return Contract(
        rig="fertilizer", quantities=QUANTITIES, rows=cfg.meter.rows,
        binding_file=Path(w.binding_file), default_binding_file=DEFAULT_BINDING,
        dut_node="Controller",
        canopen_nodes=(CanopenNode("analog output module", analog,
                                   Path(w.analog_output_eds_file)),),
        bitrate_bps=w.bitrate_bps, command_ids=frozenset({0x200 + analog}),
        node_ids=node_ids,
        periods_ms={"target_flow": float(w.setpoint_period_ms),
                    "calibration_grams_per_rev": float(cfg.calibration_test.frame_period_ms),
                    "wheel_speed": float(w.ground_speed_period_ms),
                    "wheel_based_speed": float(w.tractor_speed_period_ms),
                    "row_flow": sensor.report_period_s * 1000.0},
        dispersion_file=Path(__file__).with_name("dispersion.toml"),
        control_period_ms=100.0, physics_period_ms=1.0,
        command_quantities=("motor_command",),
        fixed_ids={"motor_command": 0x200 + analog, "dut_nmt_state": 0x700 + w.dut_node_id},
        fixed_id_reasons={
            "motor_command": f"RPDO1 of the analog output module, node {analog:#x}, as its "
                             f"EDS maps it",
            "dut_nmt_state": f"the DUT's CANopen heartbeat, 0x700 + node {w.dut_node_id:#x}"},
        dut_node_id=w.dut_node_id)
