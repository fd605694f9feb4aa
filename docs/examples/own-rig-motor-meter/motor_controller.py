"""Speed controllers for the motor-and-meter rig, a few lines each (agrihil's worked example).

``PiSpeed`` holds the meter's speed at the terminal's set-point: feed-forward from the set-point
plus a PI on the sensed speed (integrating only near the set-point: no wind-up during a step
or while its commands do not reach the drive), stepped on every SYNC, with a CANopen boot-up
and heartbeat. ``OpenLoopSpeed`` is the must-fail one: it
sets the voltage from the set-point alone with a wrong motor constant and ignores the sensor.
"""

from pathlib import Path

import can
import cantools

from hil.dut.inprocess import Controller

DBC = cantools.database.load_file(str(Path(__file__).with_name("motor_meter.dbc")))
SYNC, PERIOD_S, NODE_ID = 0x080, 0.1, 0x10


class PiSpeed(Controller):
    name = "pi-speed"
    kp, ki, near, rpm_per_volt = 0.02, 0.1, 10.0, 20.0

    def __init__(self) -> None:
        self.target = self.speed = self.integral = 0.0

    def on_start(self) -> list[can.Message]:
        return [self.nmt_state(0x00)]                    # CANopen boot-up

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == SYNC:                   # one step per SYNC, and a heartbeat
            return [self.command(self.voltage()), self.nmt_state(0x05)]
        try:
            values = DBC.decode_message(msg.arbitration_id, msg.data)
        except KeyError:
            return []
        self.target = values.get("SpeedTarget", self.target)
        self.speed = values.get("Speed", self.speed)
        return []

    def voltage(self) -> float:
        error = self.target - self.speed
        if abs(error) < self.near:                       # integrate near the target only
            self.integral += self.ki * error * PERIOD_S
        return self.target / self.rpm_per_volt + self.kp * error + self.integral

    @staticmethod
    def nmt_state(state: int) -> can.Message:
        return can.Message(arbitration_id=0x700 + NODE_ID, data=[state], is_extended_id=False)

    @staticmethod
    def command(volts: float) -> can.Message:
        data = DBC.encode_message("DriveCommand", {"Voltage": min(max(volts, 0.0), 12.0)})
        return can.Message(arbitration_id=0x220, data=data, is_extended_id=False)


class OpenLoopSpeed(PiSpeed):
    name = "open-loop-speed"
    rpm_per_volt = 24.0          # the motor constant guessed wrong, and no feedback

    def voltage(self) -> float:
        return self.target / self.rpm_per_volt
