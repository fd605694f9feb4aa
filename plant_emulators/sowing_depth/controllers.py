"""A minimal in-process depth controller shipped with the rig (``--dut builtin:pi``).

Not the paper's fuzzy self-tuning PID (that is a reference controller of its own): a plain PI
on the inclinometer's depth (eq. 13 of [D]) driving the servo cylinder in profile velocity mode,
so the rig can be exercised before the reference controllers exist. It is the CANopen master of
the drive, as the terminal of [D] is: NMT start on the drive's boot-up, the CiA 402 enable
sequence from the statusword, fault reset when the drive reports a fault. PDOs go through
canopen's PDO maps read from the drive's EDS; plain frames through the rig's DBC.
"""

from __future__ import annotations

import can
import canopen

from hil.dut import Controller
from hil.rig.canopen_device import OutboxNetwork
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.frames import (
    EDS_PATH,
    ControllerStatus,
    DepthSetpoint,
    FrameCodec,
    InclinometerFrame,
)
from plant_emulators.sowing_depth.sensors import calibration_depth_mm

MODE_PROFILE_VELOCITY = 3
# CiA 402 controlwords
SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, FAULT_RESET = 0x06, 0x07, 0x0F, 0x80


def next_controlword(statusword: int) -> int:
    """The controlword that moves a CiA 402 drive one step towards Operation enabled."""
    if statusword & 0x0008:                       # Fault
        return FAULT_RESET
    if statusword & 0x004F == 0x0040:             # Switch on disabled
        return SHUTDOWN
    if statusword & 0x006F == 0x0021:             # Ready to switch on
        return SWITCH_ON
    if statusword & 0x006F in (0x0023, 0x0027):   # Switched on / Operation enabled
        return ENABLE_OPERATION
    return SHUTDOWN


class PiDepthController(Controller):
    name = "builtin-depth-pi"
    kp_per_s = 1.5          # rod speed (mm/s) per mm of depth error
    ki_per_s2 = 1.0
    max_speed_mm_s = 50.0   # the cylinder's rated rod speed

    def __init__(self) -> None:
        cfg = load_rig_config()
        wiring = cfg.wiring
        self.period_s = wiring.sync_period_ms / 1000.0
        self.node_id = wiring.drive_node_id
        self.codec = FrameCodec()
        self.network = OutboxNetwork()
        self.drive = canopen.RemoteNode(self.node_id, str(EDS_PATH))
        self.network.add_node(self.drive)
        self.drive.rpdo.read(from_od=True)
        self.drive.tpdo.read(from_od=True)
        self.ids = {"incl": wiring.inclinometer_frame_id,
                    "setpoint": wiring.depth_setpoint_frame_id}
        self.drive_nmt = 0x00
        self.statusword = 0
        self.last_controlword = 0
        self.mode_sent = False
        self.target_mm = 30.0
        self.enabled = False
        self.depth_mm: float | None = None
        self.integral = 0.0
        self.syncs = 0

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        can_id = msg.arbitration_id
        if can_id == 0x700 + self.node_id:
            self.drive_nmt = msg.data[0]
            if self.drive_nmt != 0x05:             # boot-up or pre-operational: start it
                return [can.Message(arbitration_id=0x000, is_extended_id=False,
                                    data=bytes([0x01, self.node_id]))]
        elif can_id == self.ids["incl"]:
            frame = self.codec.decode(msg)
            assert isinstance(frame, InclinometerFrame)
            if frame.x_status == "ok":
                depth = calibration_depth_mm(frame.x_mv)
                self.depth_mm = depth if self.depth_mm is None else (
                    self.depth_mm + 0.2 * (depth - self.depth_mm))
        elif can_id == self.ids["setpoint"]:
            frame = self.codec.decode(msg)
            assert isinstance(frame, DepthSetpoint)
            self.target_mm = frame.target_depth_mm
            self.enabled = frame.enable == "on" and frame.mode == "automatic"
        elif can_id in (0x180 + self.node_id, 0x280 + self.node_id):
            self.network.notify(can_id, bytes(msg.data), msg.timestamp)
            pdo = 1 if can_id == 0x180 + self.node_id else 2
            self.statusword = int(self.drive.tpdo[pdo]["Statusword"].raw)
        elif can_id == 0x080:
            return self.on_sync()
        return []

    def on_sync(self) -> list[can.Message]:
        self.syncs += 1
        out: list[can.Message] = []
        if not self.mode_sent and self.drive_nmt == 0x05:
            self.drive.rpdo[3]["Modes of operation"].raw = MODE_PROFILE_VELOCITY
            self.drive.rpdo[3].transmit()
            self.mode_sent = True
        speed = 0.0
        controlword = next_controlword(self.statusword)
        if controlword == FAULT_RESET and self.last_controlword == FAULT_RESET:
            controlword = 0x00     # fault reset acts on a rising edge of bit 7: drop it first
        self.last_controlword = controlword
        if self.enabled and self.depth_mm is not None and controlword == ENABLE_OPERATION:
            error = self.target_mm - self.depth_mm
            limit = self.max_speed_mm_s
            self.integral = min(max(self.integral + self.ki_per_s2 * error * self.period_s,
                                    -limit), limit)
            speed = min(max(self.kp_per_s * error + self.integral, -limit), limit)
        else:
            self.integral = 0.0
        self.drive.rpdo[2]["Controlword"].raw = controlword
        self.drive.rpdo[2]["Target velocity"].raw = round(speed * 100)   # 0.01 mm/s
        self.drive.rpdo[2].transmit()
        if self.syncs % 10 == 0:
            out.append(self.codec.encode(ControllerStatus(
                measured_depth_mm=self.depth_mm or 0.0, roller_position_command_mm=0.0,
                state="controlling" if self.enabled else "ready", counter=self.syncs % 16)))
        return self.network.take() + out
