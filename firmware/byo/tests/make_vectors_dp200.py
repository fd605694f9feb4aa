"""Write the DP-200 build's frame vectors from the Python build (reference_controllers/
sowing_depth/dbc_adapter.py), for the C build to replay (firmware/byo/tests/replay_dp200.c).

A vector file is the DP-200 controller fed a seeded sequence of its own frames by a small
stand-in of its machine: a servo drive that boots, answers the SDO writes of its configuration
(confirming each, or refusing one with an abort, or answering out of turn), takes the NMT start,
runs CiA 402's state machine on the controlwords it gets, falls into Fault and reboots; a rod
that moves at the commanded speed; an inclinometer on the sensor hub whose depth follows the rod
(with noise, frozen stretches, a broken wire, the draw-wire channel, an undefined channel and
short frames); the terminal's job (every Enable and Mode); GBSD speeds (valid, "not available",
below the control threshold, from another source address, silent for seconds); the drive's
diagnosis. One line per event, and every frame the Python build sent in answer, as
make_vectors.py writes the RC-400's::

    params kp0=3.0 ki0=0.1 kd0=0.0
    boot                      the controller starts (on_start)
    in 702 s 00               a received frame: id (hex), s/x (standard/extended), data (hex)
    out 602 s 2f00140000...   a frame sent in answer to the event above, in order
    step                      one control step (a SYNC)

The C replay must send the same frames, byte for byte. Run from the repository root::

    .venv/bin/python firmware/byo/tests/make_vectors_dp200.py firmware/byo/tests/data-dp200

(tests/firmware/test_dp200_firmware.py checks that the committed files are what this writes.)
"""

from __future__ import annotations

import argparse
import random
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import cantools

from reference_controllers.sowing_depth.dbc_adapter import (
    DP200_DATABASE,
    DP200_SIGNALS,
    DbcDepthController,
)

#: file name -> (the controller's parameters, how the drive answers its configurations)
VECTORS: dict[str, tuple[dict[str, Any], tuple[str, ...]]] = {
    # the DUT profile's gains; every configuration confirmed
    "dp200-profile.txt": ({"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}, ("ok",)),
    # the core's own defaults, a shorter freeze check; every configuration confirmed
    "dp200-defaults.txt": ({"frozen_after_s": 0.1, "hold_gain_per_s": 2.0}, ("ok",)),
    # refused (an abort), answered out of turn, an unexpected answer, then confirmed
    "dp200-refused.txt": ({"kp0": 3.0, "ki0": 0.1, "kd0": 0.0},
                          ("abort", "wrong-object", "unexpected", "ok")),
}
SEED = 28
STEPS = 900
DRIVE_BOOTS = (5, 300, 610, 760)         # the drive boots (power-up, reset) at these steps
PRE_OPERATIONAL_AT = 470             # the drive reports pre-operational once, unasked
ABORT_CODE = 0x06040041              # object cannot be mapped to the PDO
FAULT_AT = (200, 520)                # the drive falls into Fault
FROZEN = ((120, 160), (700, 720))    # the inclinometer repeats one voltage
BROKEN = ((250, 262), (560, 575))    # its X output reads OpenCircuit
SPEED_SILENT = (380, 520)            # no GBSD for 1.4 s


class Machine:
    """The DP-200's machine, encoded through its own database."""

    def __init__(self, rnd: random.Random, answers: tuple[str, ...]) -> None:
        self.db = cantools.database.load_file(str(DP200_DATABASE))
        self.rnd = rnd
        self.answers = list(answers)
        self.mode = "ok"
        self.nmt = -1                # the drive's NMT state, -1 off
        self.statusword = 0x0040     # Switch on disabled
        self.position = 2000         # 0.01 mm
        self.requests: list[bytes] = []
        self.alive = 0
        self.x_raw = 3698
        self.error_code = 0

    def msg(self, name: str, values: dict[str, Any]) -> can.Message:
        m = self.db.get_message_by_name(name)
        return can.Message(arbitration_id=m.frame_id, is_extended_id=m.is_extended_frame,
                           data=m.encode(values, scaling=False, strict=False))

    def boot(self) -> can.Message:
        self.nmt, self.statusword = 127, 0x0040
        self.mode = self.answers.pop(0) if self.answers else "ok"
        return self.msg("DP_DriveHeartbeat", {"NmtState": 0})

    def take(self, sent: list[can.Message]) -> None:
        """What the drive does with the controller's frames."""
        for m in sent:
            if m.arbitration_id == 0x602:
                self.requests.append(bytes(m.data))
            elif m.arbitration_id == 0x000 and bytes(m.data) == b"\x01\x02" and self.nmt > 0:
                self.nmt = 5
            elif m.arbitration_id == 0x302 and self.nmt == 5:
                values = self.db.decode_message(0x302, bytes(m.data), scaling=False)
                self.command(int(values["Controlword"]), int(values["TargetVelocity"]))

    def command(self, controlword: int, velocity: int) -> None:
        """CiA 402, enough of it: the controlword moves the state, the rod runs at 1 ms."""
        sw = self.statusword
        if sw & 0x0008:
            self.statusword = 0x0040 if controlword & 0x80 else sw
        elif controlword == 0x06:
            self.statusword = 0x0021
        elif controlword == 0x07 and sw & 0x006F == 0x0021:
            self.statusword = 0x0023
        elif controlword == 0x0F and sw & 0x006F in (0x0023, 0x0027):
            self.statusword = 0x0027
        if self.statusword & 0x006F == 0x0027:
            self.position = max(0, min(10000, self.position + round(velocity / 100)))

    def sdo_answers(self, count: int) -> Iterator[can.Message]:
        """Answers to the first ``count`` requests waiting, in order."""
        for data in self.requests[:count]:
            index, sub = int.from_bytes(data[1:3], "little"), data[3]
            command, value = 0x60, 0
            if self.mode == "abort" and (index, sub) == (0x1600, 2):
                command, value = 0x80, ABORT_CODE
            elif self.mode == "wrong-object" and (index, sub) == (0x1A00, 1):
                index = 0x1A01
            elif self.mode == "unexpected" and (index, sub) == (0x1800, 5):
                command = 0x4B
            yield self.msg("DP_DriveSdoResponse", {"Command": command, "Index": index,
                                                   "SubIndex": sub, "Data": value})
        del self.requests[:count]

    def feedback(self) -> can.Message:
        return self.msg("DP_DriveFeedback", {"PositionActual": self.position,
                                             "Statusword": self.statusword,
                                             "ModeDisplay": 3})

    def inclinometer(self, step: int) -> can.Message:
        """ArmTiltX from the rod's position (deeper with the rod), 1 mV counts, with noise."""
        frozen = any(a <= step < b for a, b in FROZEN)
        if not frozen:
            depth = 12.0 + 0.45 * self.position / 100.0 + self.rnd.gauss(0.0, 0.15)
            self.x_raw = round((270.35 - depth) / 0.065)
        state = 2 if any(a <= step < b for a, b in BROKEN) else (
            0 if self.rnd.random() < 0.01 else 1)
        return self.msg("DP_SensorHub", {"Channel": 0, "ArmTiltX": self.x_raw,
                                         "ArmTiltY": 2500, "TiltXState": state,
                                         "TiltYState": 1, "TiltSeq": step % 16})

    def draw_wire(self, step: int) -> can.Message:
        return self.msg("DP_SensorHub", {"Channel": 1, "RollerTravel": self.position * 10,
                                         "WireState": 1, "WireSeq": step % 16})

    def setpoint(self) -> can.Message:
        r = self.rnd
        self.alive = (self.alive + 1) % 8
        enable = r.choices((2, 1, 3, 0), (20, 2, 1, 1))[0]
        mode = r.choices((2, 1, 3, 0, 7, 5), (20, 2, 1, 1, 1, 1))[0]
        return self.msg("DP_Setpoint", {"TargetDepth": r.choice((300, 300, 350, 400, 200,
                                                                 r.randrange(150, 450))),
                                        "ManualRoller": 2000, "Enable": enable, "Mode": mode,
                                        "Alive": self.alive})

    def speed(self) -> can.Message:
        r = self.rnd
        raw = r.choices((round(r.gauss(1111, 20)), 0xFFFF, 60, 0xFB00), (30, 1, 2, 1))[0]
        msg = self.msg("GBSD", {"GroundBasedMachineSpeed": raw, "GroundBasedMachineDistance": 0,
                                "GroundBasedDirection": 1})
        if r.random() < 0.05:                             # another source address: not ours
            msg.arbitration_id = (msg.arbitration_id & ~0xFF) | 0x2A
        return msg

    def diagnosis(self) -> can.Message:
        if self.rnd.random() < 0.1:
            self.error_code = self.rnd.choice((0, 0x2310, 0x7121, 0xFF00))
        return self.msg("DP_DriveDiagnosis", {"ErrorCode": self.error_code,
                                              "CurrentActual": self.rnd.randrange(-500, 500)})


def events(m: Machine, rnd: random.Random) -> Iterator[can.Message | None]:
    """The input: frames, None for a control step. The controller's answers reach the machine
    through :meth:`Machine.take` (the caller hands them over)."""
    for step in range(STEPS):
        if step in DRIVE_BOOTS:
            yield m.boot()
        elif step == PRE_OPERATIONAL_AT:
            m.nmt = 127
            yield m.msg("DP_DriveHeartbeat", {"NmtState": 127})
        if m.requests:                                    # the drive's SDO server answers,
            yield from m.sdo_answers(rnd.choice((len(m.requests), 1 + len(m.requests) // 2)))
        if m.nmt > 0 and step % 10 == 0:
            yield m.msg("DP_DriveHeartbeat", {"NmtState": m.nmt})
        if step in FAULT_AT and m.nmt == 5:
            m.statusword = 0x0008 | 0x0200
        if m.nmt == 5:
            yield m.feedback()
        if step % 10 == 3:
            yield m.setpoint()
        if step % 10 == 7 and not SPEED_SILENT[0] <= step < SPEED_SILENT[1]:
            yield m.speed()
        if m.nmt == 5 and step % 10 == 5:
            yield m.diagnosis()
        yield m.inclinometer(step)
        if step % 2:
            yield m.draw_wire(step)
        if rnd.random() < 0.02:                           # an undefined channel, short frames
            yield can.Message(arbitration_id=0x1A5, is_extended_id=False,
                              data=bytes([5, 0x0E, 0x74, 0, 0, 0x40, 0, 0]))
        if rnd.random() < 0.02:
            yield can.Message(arbitration_id=rnd.choice((0x20A, 0x1A2, 0x582)),
                              is_extended_id=False, data=bytes([1, 2, 3]))
        if rnd.random() < 0.01:                           # an answer nobody asked for
            yield m.msg("DP_DriveSdoResponse", {"Command": 0x60, "Index": 0x6060,
                                                "SubIndex": 0, "Data": 0})
        yield None


def _line(kind: str, msg: can.Message) -> str:
    return f"{kind} {msg.arbitration_id:x} {'x' if msg.is_extended_id else 's'} " \
           f"{bytes(msg.data).hex()}"


def write(path: Path, params: dict[str, Any], answers: tuple[str, ...]) -> None:
    ctl = DbcDepthController(DP200_DATABASE, DP200_SIGNALS, params)
    lines = [f"# {path.name}: written by firmware/byo/tests/make_vectors_dp200.py (seed {SEED}) "
             "from reference_controllers/sowing_depth/dbc_adapter.py; do not edit",
             "params " + " ".join(f"{k}={v}" for k, v in params.items()),
             "boot", *(_line("out", m) for m in ctl.on_start())]
    rnd = random.Random(SEED)
    machine = Machine(rnd, answers)
    for msg in events(machine, rnd):
        if msg is None:
            lines.append("step")
            sent = ctl.step()
        else:
            lines.append(_line("in", msg))
            sent = ctl.on_frame(msg)
        lines.extend(_line("out", m) for m in sent)
        machine.take(sent)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="directory to write the vector files into")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, (params, answers) in VECTORS.items():
        write(args.out / name, params, answers)
    return 0


if __name__ == "__main__":
    sys.exit(main())
