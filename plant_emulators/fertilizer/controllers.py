"""Minimal in-process flow controllers shipped with the rig (``--dut builtin:pi``).

They exist so the rig can be driven before the reference controllers (the papers' piecewise
PID as C firmware and daemon) are built; they are *not* those controllers. Each reads only what
a real controller reads (setpoints, flow modules, ground speed) and writes only the analog
module's RPDO, a status frame and its heartbeat, all through the rig's DBC.

* ``pi``: feedforward from the meter's nominal flow map plus an integral correction applied
  once per new flow report (the sensor reports once per second, so faster action only chases
  stale data);
* ``open-loop``: the feedforward alone: the constant-speed baseline of [F].
"""

from __future__ import annotations

import can

from hil.dut import Controller
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.frames import FertilizerDatabase

#: the meter's nominal map as its data sheet would give it: q = c·n^p g/s per row (n r/min)
NOMINAL_FLOW_COEFF = 4.586
NOMINAL_FLOW_EXPONENT = 0.6537
#: drive scaling: 10 V → 3,000 motor rpm → 60 r/min at the meter shaft (50:1)
SHAFT_RPM_PER_V = 6.0


def feedforward_volts(target_gps: float) -> float:
    if target_gps <= 0:
        return 0.0
    shaft_rpm = (target_gps / NOMINAL_FLOW_COEFF) ** (1.0 / NOMINAL_FLOW_EXPONENT)
    return min(10.0, shaft_rpm / SHAFT_RPM_PER_V)


class PiFlowController(Controller):
    name = "builtin-pi"
    #: fraction of the relative flow error corrected per sensor report
    integral_gain = 0.6

    def __init__(self, closed_loop: bool = True) -> None:
        self.db = FertilizerDatabase.from_config(load_rig_config())
        self.closed_loop = closed_loop
        self.ids = {name: self.db.frame_id(name) for name in
                    ("FertSetpoint", "GroundWheelSpeed", "AnalogOutputCommand")}
        self.flow_ids = {self.db.frame_id(f"FlowModule{i}"): i for i in range(1, 5)}
        self.setpoint: dict[str, float] = {}
        self.flows: dict[int, float] = {}
        self.new_report = False
        self.wheel_speed = 0.0
        self.correction = 0.0
        self.syncs = 0
        self.command_v = 0.0

    def target_gps(self) -> float:
        sp = self.setpoint
        if not sp or not sp.get("Enable"):
            return 0.0
        if int(sp["Mode"]) == 0:
            rows = max(1, int(sp.get("ActiveRows", 4)))
            return 0.1 * sp["TargetRate"] * sp["WorkingWidth"] * self.wheel_speed / rows
        return float(sp["TargetFlow"])

    def on_start(self) -> list[can.Message]:
        """The CANopen boot-up message (heartbeat state 0): a node announces itself before it
        sends anything else (CiA 301; judged by bus conformance)."""
        return [self.db.heartbeat("ControllerHeartbeat", 0x00)]

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        can_id = msg.arbitration_id
        if can_id == self.ids["FertSetpoint"]:
            self.setpoint = {k: float(v) for k, v in self.db.decode(msg)[1].items()}
        elif can_id in self.flow_ids:
            signals = self.db.decode(msg)[1]
            if signals["BaselineReady"]:
                self.flows[self.flow_ids[can_id]] = float(signals["Flow"])
                self.new_report = True
        elif can_id == self.ids["GroundWheelSpeed"]:
            self.wheel_speed = float(self.db.decode(msg)[1]["WheelSpeed"])
        elif can_id == 0x080:
            return self.on_sync()
        return []

    def on_sync(self) -> list[can.Message]:
        self.syncs += 1
        target = self.target_gps()
        if target <= 0:
            self.correction = 0.0
        elif self.closed_loop and self.new_report and self.flows:
            measured = sum(self.flows.values()) / len(self.flows)
            self.correction += self.integral_gain * (target - measured) / target
            self.correction = min(max(self.correction, -0.5), 0.5)
        self.new_report = False
        self.command_v = min(10.0, feedforward_volts(target) * (1.0 + self.correction))
        out = [self.db.analog_output_command(ch1_mv=round(self.command_v * 1000))]
        if self.syncs % 10 == 1:
            measured = sum(self.flows.values()) / len(self.flows) if self.flows else 0.0
            out.append(self.db.controller_status(
                target_flow_gps=min(target, 250.0), measured_flow_gps=min(measured, 250.0),
                command_v=self.command_v, pid_segment=0, mode=int(self.setpoint.get("Mode", 1)),
                enabled=bool(self.setpoint.get("Enable", 0)), sensor_fault=False,
                counter=self.syncs))
        # the analog module watches this heartbeat with a 300 ms consumer time (0x1016):
        # produce it every control period, well inside that
        out.append(self.db.heartbeat("ControllerHeartbeat", 0x05))
        return out


class OpenLoopController(PiFlowController):
    name = "builtin-open-loop"

    def __init__(self) -> None:
        super().__init__(closed_loop=False)


