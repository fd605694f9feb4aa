"""A toy rig and controller for testing the run loop: a first-order tank whose level sensor
reports at 20 Hz; a P controller answers SYNC with a pump command. Frames are packed with
struct here because this is a test fixture, not a rig the project ships."""

from __future__ import annotations

import struct
from typing import ClassVar

import can

from hil.dut import Controller
from hil.rig import PeriodicDevice, Rig, RigContext

SENSOR_ID, COMMAND_ID, SETPOINT_ID = 0x181, 0x201, 0x301


class LevelSensor(PeriodicDevice):
    def __init__(self, rig: ToyRig) -> None:
        super().__init__("level sensor", 0.05)
        self.rig = rig

    def frames(self, time_s: float) -> list[can.Message]:
        noisy = self.rig.level + self.rig.noise[int(time_s * 20) % len(self.rig.noise)]
        return [can.Message(arbitration_id=SENSOR_ID, is_extended_id=False,
                            data=struct.pack("<f", noisy))]


class SetpointTerminal(PeriodicDevice):
    def __init__(self, rig: ToyRig) -> None:
        super().__init__("terminal", 0.1)
        self.rig = rig

    def frames(self, time_s: float) -> list[can.Message]:
        return [can.Message(arbitration_id=SETPOINT_ID, is_extended_id=False,
                            data=struct.pack("<f", self.rig.setpoint))]


class ToyRig(Rig):
    name = "toy"
    inputs: ClassVar[dict[str, str]] = {"setpoint": "m", "ground_speed_mps": "m/s"}
    faults: ClassVar[dict[str, str]] = {"sensor_silent": "the level sensor stops sending"}

    def __init__(self, ctx: RigContext) -> None:
        super().__init__(ctx)
        self.level = 0.0
        self.pump = 0.0
        self.setpoint = 0.0
        self.time_s = 0.0
        self.noise = list(ctx.rng.normal(0.0, 0.01, 1000))
        self.sensor = LevelSensor(self)
        self.devices = [self.sensor, SetpointTerminal(self)]

    def advance(self, n: int, dt: float) -> None:
        level, pump = self.level, self.pump
        for _ in range(n):
            level += dt * (pump - level) / 0.5
        self.level = level
        self.time_s += n * dt

    def set_input(self, name: str, value: float, time_s: float) -> None:
        if name == "setpoint":
            self.setpoint = value

    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        self.sensor.silent = active

    def command_ids(self) -> frozenset[int]:
        return frozenset({COMMAND_ID})

    def on_dut_frame(self, msg: can.Message, time_s: float) -> None:
        if msg.arbitration_id == COMMAND_ID:
            self.pump = struct.unpack("<f", bytes(msg.data))[0]

    def trace_signals(self) -> dict[str, tuple[float, str]]:
        return {"level": (self.level, "m"), "pump": (self.pump, "m"),
                "setpoint": (self.setpoint, "m")}

    def truth(self) -> dict[str, object]:
        return {"final_level_m": self.level}


class ToyController(Controller):
    name = "toy-p"

    def __init__(self, gain: float = 3.0, die_after_syncs: int | None = None) -> None:
        self.gain = gain
        self.level = 0.0
        self.setpoint = 0.0
        self.syncs = 0
        self.die_after_syncs = die_after_syncs

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == SENSOR_ID:
            self.level = struct.unpack("<f", bytes(msg.data))[0]
        elif msg.arbitration_id == SETPOINT_ID:
            self.setpoint = struct.unpack("<f", bytes(msg.data))[0]
        elif msg.arbitration_id == 0x080:
            self.syncs += 1
            if self.die_after_syncs is not None and self.syncs > self.die_after_syncs:
                return []   # goes silent
            u = self.setpoint + self.gain * (self.setpoint - self.level)
            return [can.Message(arbitration_id=COMMAND_ID, is_extended_id=False,
                                data=struct.pack("<f", u))]
        return []
