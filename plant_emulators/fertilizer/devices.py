"""The fertilizer rig's CAN nodes, as the controller under test sees them.

Each node hands the values of its rig quantities (:data:`~plant_emulators.fertilizer.frames.
QUANTITIES`) to the bus contract's codec (:class:`hil.contract.codec.ContractCodec`), which
encodes them into the frames of the binding in force: the rig's own DBC, or the DUT's database.
The CANopen analog output module speaks its EDS; nothing here packs bytes by hand.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import can

from hil.rig.canopen_device import CanopenDevice
from hil.rig.device import PeriodicDevice

if TYPE_CHECKING:
    from collections.abc import Callable

    from hil.contract.codec import ContractCodec
    from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
    from plant_emulators.fertilizer.calibration_test import CalibrationTest
    from plant_emulators.fertilizer.flow_sensor import FlowReport, FlowSensor
    from plant_emulators.fertilizer.ground_speed import GroundSpeedModel, TractorSpeedReport

from plant_emulators.fertilizer.flow_sensor import SensorStatus

#: how often a flow module's firmware is polled for finished windows: its reports go out
#: within this long of the window closing
FLOW_POLL_S = 0.01


class FlowModuleDevice(PeriodicDevice):
    """Capacitive flow detection module of one row: sends each finished window's report.

    ``stale``: the module keeps sending its last report unchanged (frozen firmware)."""

    def __init__(self, row: int, sensor: FlowSensor, codec: ContractCodec,
                 valid_max_gps: float) -> None:
        super().__init__(f"flow module {row}", FLOW_POLL_S)
        self.row = row
        self.sensor = sensor
        self.codec = codec
        #: the largest flow a module reports as valid (the quantity's range): a ``garbage``
        #: module's larger values are encoded without the carrier's range check
        self.valid_max_gps = valid_max_gps
        self.stale = False
        self.last: FlowReport | None = None
        self.reported_flow_gps = math.nan

    def frames(self, time_s: float) -> list[can.Message]:
        reports = self.sensor.take_reports()
        if self.stale:
            return self.encode(self.last) if reports and self.last else []
        out = []
        for report in reports:
            self.last = report
            self.reported_flow_gps = report.flow_gps
            out += self.encode(report)
        return out

    def encode(self, report: FlowReport) -> list[can.Message]:
        """The frames of one report: its quantities through the codec."""
        status = SensorStatus(report.status)
        garbage = report.flow_gps > self.valid_max_gps \
            or report.grams_in_window > self.valid_max_gps
        return self.codec.encode({
            "row_flow": _clip_low(report.flow_gps),
            "row_window_mass": _clip_low(report.grams_in_window),
            "row_counter": report.counter,
            "row_baseline_ready": int(SensorStatus.BASELINE_READY in status),
            "row_sliding_window": int(SensorStatus.SLIDING_WINDOW in status),
            "row_adc_overrange": int(SensorStatus.ADC_OVERRANGE in status),
            "row_intercept_applied": int(SensorStatus.INTERCEPT_APPLIED in status),
            "row_window_length": round(report.window_s * 1000.0),
        }, row=self.row, strict=not garbage)

    def emit(self, time_s: float) -> list[can.Message]:
        if self.silent:
            self.sensor.take_reports()   # the firmware keeps measuring; nothing leaves the node
            return []
        return self.frames(time_s)

    def next_due(self, time_s: float) -> float:
        """The next poll that can find a report: polls before the sensor's next window end
        find nothing and send nothing whatever the faults, so the runner need not make them
        (a report every second, a poll every 10 ms). The poll that takes a report is the same
        as with every poll made: the first one at or after the step that produced it."""
        poll = super().next_due(time_s)
        sensor = self.sensor
        ready, step = sensor.next_report_time_s(), sensor.step_s
        if ready is None or step is None or sensor.reports_pending:
            return poll
        # the first poll at or after the report's step: half a physics step of margin keeps
        # float rounding of the two time grids out of the comparison
        return max(poll, super().next_due(ready - 0.5 * step))


class GroundWheelDevice(PeriodicDevice):
    """The Hall ground-wheel speed node of [F]."""

    def __init__(self, speed: GroundSpeedModel, codec: ContractCodec, period_s: float) -> None:
        super().__init__("ground wheel speed", codec.period_s("wheel_speed", period_s))
        self.speed = speed
        self.codec = codec
        self.counter = 0

    def frames(self, time_s: float) -> list[can.Message]:
        self.counter = (self.counter + 1) % 256
        report = self.speed.hall_report()
        return self.codec.encode({
            "wheel_speed": min(report.wheel_speed_mps, 20.0),
            "wheel_pulse_count": report.pulse_count % 65536,
            "wheel_pulse_period": min(report.last_period_s, 6.5535),
            "wheel_counter": self.counter,
            "wheel_moving": int(report.moving),
        })


class TractorSpeedDevice(PeriodicDevice):
    """The tractor ECU's ISO 11783 speed messages: PGN 65096 (wheel) and 65097 (ground)."""

    def __init__(self, speed: GroundSpeedModel, codec: ContractCodec, period_s: float) -> None:
        # one period for both messages: the cycle of the first one the binding carries
        first = next((q for q in ("wheel_based_speed", "ground_based_speed") if codec.carries(q)),
                     "wheel_based_speed")
        super().__init__("tractor ECU speed", codec.period_s(first, period_s))
        self.speed = speed
        self.codec = codec

    def frames(self, time_s: float) -> list[can.Message]:
        return [*self.codec.encode(_speed_values("wheel_based",
                                                 self.speed.wheel_based_report())),
                *self.codec.encode(_speed_values("ground_based",
                                                 self.speed.ground_based_report()))]


class TerminalDevice(PeriodicDevice):
    """The operator terminal / task controller sending setpoints to the controller."""

    def __init__(self, codec: ContractCodec, period_s: float, rows: int) -> None:
        super().__init__("terminal setpoints", codec.period_s("target_flow", period_s))
        self.codec = codec
        self.rows = rows
        self.mode = 1
        self.enable = True
        self.target_flow_gps = 0.0
        self.rate_kg_per_hm2 = 0.0
        self.width_m = 0.0
        self.speed_source = 0
        self.counter = 0

    def frames(self, time_s: float) -> list[can.Message]:
        self.counter += 1
        return self.codec.encode({
            "target_rate": self.rate_kg_per_hm2,
            "working_width": self.width_m,
            "target_flow": self.target_flow_gps,
            "mode": self.mode,
            "enable": int(self.enable),
            "speed_source": self.speed_source,
            "active_rows": self.rows,
            "setpoint_counter": self.counter % 256,
        })


class CalibrationDevice(PeriodicDevice):
    """The terminal's stored calibration test of the lot (MeterCalibration), repeated every
    ``period_s`` while there is one; ``test`` returns it (None: no test was made)."""

    def __init__(self, codec: ContractCodec, period_s: float,
                 test: Callable[[], CalibrationTest | None]) -> None:
        super().__init__("terminal calibration", codec.period_s("calibration_grams_per_rev",
                                                                period_s))
        self.codec = codec
        self.test = test

    def frames(self, time_s: float) -> list[can.Message]:
        test = self.test()
        if test is None:
            return []
        return self.codec.encode({
            "calibration_grams_per_rev": test.grams_per_rev_row,
            "calibration_shaft_speed": test.shaft_speed_rpm,
            "calibration_revolutions": test.revolutions,
        })


#: ISO 11783-7 distances wrap at the field's maximum (4211081.215 m)
DISTANCE_WRAP_M = 4211081.215


def _speed_values(source: str, report: TractorSpeedReport) -> dict[str, float | int]:
    """The quantities of one tractor speed message (``source``: wheel_based, ground_based)."""
    return {f"{source}_speed": report.speed_mps,
            f"{source}_distance": report.distance_m % DISTANCE_WRAP_M,
            f"{source}_direction": int(report.direction)}


def _clip_low(value: float, low: float = 0.0) -> float:
    return value if value > low else low


#: EMCY error code "life guard error or heartbeat error" (CiA 301)
HEARTBEAT_ERROR = 0x8130


class AnalogOutputModule(CanopenDevice):
    """The C-3402 CAN analog output module (CiA 401): the controller writes the motor command
    to 0x6411 sub 1 (mV) by RPDO; the module drives the motor's 0-10 V speed input.

    It consumes the controller's heartbeat (0x1016): when the heartbeat is missing for longer
    than the consumer time, the outputs whose error mode (0x6443) is on go to their error value
    (0x6444), which is the motor's safe state, until the heartbeat returns. The timeout is
    error 0x8130 (error register bit 4, communication): an EMCY, an entry in 0x1003; the
    heartbeat's return sends the error-reset EMCY. A master may set another node or time in
    0x1016 sub 1 (node 0 or time 0: no monitoring); monitoring of the new node starts at its
    first heartbeat, and an active timeout of the old one ends (error-reset EMCY)."""

    def __init__(self, node_id: int, eds: str, channel: AnalogOutputChannel,
                 output_sub: int) -> None:
        super().__init__("analog output module", node_id, eds)
        self.channel = channel
        self.output_sub = output_sub
        self.watched_node, self.consumer_time_s = self._consumer()
        self.last_watched_heartbeat_s = -math.inf
        self.heartbeat_seen = False
        self.comm_error = False
        self._volts: float | None = None

    def _consumer(self) -> tuple[int, float]:
        """The watched node and consumer time (s) of 0x1016 sub 1."""
        consumer = int(self.read(0x1016, 1))
        return (consumer >> 16) & 0x7F, (consumer & 0xFFFF) / 1000.0

    def configured(self, time_s: float) -> None:
        """0x1016 may have changed: monitor the new node from its first heartbeat."""
        watched = self._consumer()
        if watched == (self.watched_node, self.consumer_time_s):
            return
        self.watched_node, self.consumer_time_s = watched
        self.heartbeat_seen = False
        self.last_watched_heartbeat_s = -math.inf
        self._volts = None
        if self.comm_error:
            self.comm_error = False
            self.clear_error(HEARTBEAT_ERROR)

    def accepts(self, msg: can.Message) -> bool:
        if (self.watched_node and msg.arbitration_id == 0x700 + self.watched_node
                and not msg.is_extended_id):
            return True
        return super().accepts(msg)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        if self.watched_node and msg.arbitration_id == 0x700 + self.watched_node:
            self.last_watched_heartbeat_s = time_s
            self.heartbeat_seen = True
            return []
        self._volts = None          # an RPDO, SDO or NMT command may change the output
        return super().on_frame(msg, time_s)

    def update(self, time_s: float) -> None:
        """Refresh the communication-error state (called as the physics advances)."""
        if self.consumer_time_s <= 0 or not self.heartbeat_seen:
            self.comm_error = False
            return
        error = time_s - self.last_watched_heartbeat_s > self.consumer_time_s
        if error != self.comm_error:
            self.comm_error = error
            self._volts = None
            # CiA 301: heartbeat consumer timeout is EMCY 0x8130, its end the error reset
            if error:
                self.raise_error(HEARTBEAT_ERROR)
                self._error_behaviour()
            else:
                self.clear_error(HEARTBEAT_ERROR)

    def _error_behaviour(self) -> None:
        """0x1029 sub 1 on a communication error (CiA 301): 0 pre-operational (from
        operational), 1 no change of state, 2 stopped."""
        behaviour = int(self.read(0x1029, 1))
        if behaviour == 0 and self.operational:
            self.enter_state("PRE-OPERATIONAL")
        elif behaviour == 2:
            self.enter_state("STOPPED")

    def output_volts(self) -> float:
        """What the module drives onto the motor's speed input now."""
        if self._volts is None:
            self._volts = self._compute_volts()
        return self._volts

    def _compute_volts(self) -> float:
        if not self.operational:
            return self.channel.error_volts()
        if self.comm_error and int(self.read(0x6443, self.output_sub)):
            return self.channel.volts(int(self.read(0x6444, self.output_sub)))
        return self.channel.volts(int(self.read(0x6411, self.output_sub)))
