"""Write the RC-400 build's frame vectors from the Python build (reference_controllers/fertilizer/
dbc_adapter.py), for the C build to replay (firmware/byo/tests/replay_rc400.c).

A vector file is the RC-400 controller fed a seeded sequence of its own frames (set-points in
every program and speed source, multiplexed row reports with every State and Diag, speeds from
the three sources including J1939 "not available", short frames and an undefined multiplexer
value, long silences, jobs in which one row's module reads 60 % or 130 % of the flow with good
flags: the cross-row check's exclusions and readmissions), one line per event, and every frame
the Python build sent in answer::

    params mode=physical ff_coeff=4.39
    boot                      the controller starts (on_start)
    in 312 s 00c8...          a received frame: id (hex), s/x (standard/extended), data (hex)
    step                      one control step (a SYNC)
    out 292 s 0a1c...         a frame sent in answer to the event above, in order

The C replay must send the same frames, byte for byte. Run from the repository root::

    .venv/bin/python firmware/byo/tests/make_vectors.py firmware/byo/tests/data

(tests/firmware/test_byo_firmware.py checks that the committed files are what this writes.)
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

from reference_controllers.fertilizer.dbc_adapter import (
    RC400_DATABASE,
    RC400_SIGNALS,
    DbcFlowController,
)

#: file name -> the controller's parameters (a DUT profile's [parameters])
VECTORS: dict[str, dict[str, Any]] = {
    "rc400-physical.txt": {"mode": "physical", "ff_coeff": 4.390},
    "rc400-paper-literal.txt": {"mode": "paper-literal"},
    "rc400-open-loop.txt": {"mode": "open-loop", "ff_coeff": 4.390},
}
SEED = 28
JOB_STEPS = 40
STEPS = 15 * JOB_STEPS
#: (Program, Run, SpeedSrc) of each 4 s job: every program (1 SpeedRelated, 2 FixedRate,
#: 3 FixedSpeed, 0 Off) and speed source (1 WheelSensor, 2 TractorWheel, 0 Radar, 3 None)
JOBS = ((2, 1, 1), (1, 1, 1), (1, 1, 2), (1, 1, 0), (3, 1, 1), (2, 1, 0), (1, 0, 1),
        (0, 1, 2), (1, 1, 3), (2, 0, 2), (1, 1, 2), (3, 1, 0), (2, 1, 3), (1, 1, 1), (2, 1, 1))


class Frames:
    """The RC-400's input frames, encoded through its own database."""

    def __init__(self, rnd: random.Random) -> None:
        self.db = cantools.database.load_file(str(RC400_DATABASE))
        self.rnd = rnd
        self.alive = 0

    def _msg(self, name: str, values: dict[str, Any], *, strict: bool = True) -> can.Message:
        msg = self.db.get_message_by_name(name)
        return can.Message(arbitration_id=msg.frame_id, is_extended_id=msg.is_extended_frame,
                           data=msg.encode(values, strict=strict))

    def command(self, program: int, run: int, target_gps: float, source: int,
                sections: int) -> can.Message:
        r = self.rnd
        self.alive = (self.alive + 1) % 16
        return self._msg("RC_Command", {
            "RateKgHa": round(r.uniform(80.0, 400.0), 1), "WidthMm": r.randrange(1500, 6001),
            "TargetKgH": target_gps * 3.6, "Program": program, "Run": run,
            "SpeedSrc": source, "Sections": sections, "Alive": self.alive},
            strict=False)                               # Sections 0 too: below its range

    def row(self, row: int, flow_gps: float, state: int = 1, diag: int = 0) -> can.Message:
        return self._msg("RH_RowFlow", {"RowNo": row - 1, f"FlowKgH_{row}": flow_gps * 3.6,
                                        f"State_{row}": state, f"Diag_{row}": diag})

    def speed(self, source: int, mps: float | None) -> can.Message:
        """A speed of ``source`` (0 wheel sensor, 1 tractor wheel, 2 radar); None: J1939 not
        available (raw 0xFFFF) on a tractor source."""
        if source == 0:
            return self._msg("WS_GroundSpeed", {"SpeedKmh": (mps or 0.0) * 3.6})
        name = ("WheelBasedSpeedDist", "GroundBasedSpeedDist")[source - 1]
        msg = self.db.get_message_by_name(name)
        if mps is None:
            data = bytes([0xFF, 0xFF, 0, 0, 0, 0, 0, 0])
        else:
            data = msg.encode({msg.signals[0].name: mps})
        # any source address and priority: matched by PGN
        can_id = (msg.frame_id & ~0xFF) | self.rnd.choice((0xF0, 0x00, 0x2A))
        return can.Message(arbitration_id=can_id, is_extended_id=True, data=data)


def events(rnd: random.Random) -> Iterator[can.Message | None]:
    """The input: frames, None for a control step."""
    f = Frames(rnd)
    for _ in range(3):                                   # before any set-point
        yield f.row(1, 20.0)
        yield None
    target, sections = 23.0, 4
    speeds = [1.5, 1.6, 1.7]
    silent_until = 0
    wrong_row, wrong_gain = 0, 1.0
    for step in range(STEPS):
        program, run, source = JOBS[step // JOB_STEPS % len(JOBS)]
        if step % JOB_STEPS == 0 and step:               # a new job every 4 s
            target = round(rnd.uniform(5.0, 45.0), 2)
            sections = rnd.choice((4, 4, 4, 1, 2, 0, 7))
        if step % (3 * JOB_STEPS) == 0:                  # for three jobs, one module reads
            wrong_row = rnd.choice((0, 1, 2, 4))         # wrong with good flags (the
            wrong_gain = rnd.choice((0.6, 1.3))          # cross-row check)
        if step % 100 == 50:                             # the flow modules fall silent
            silent_until = step + rnd.choice((10, 30, 40))
        if step % 2 == 0:
            yield f.command(program, run, target, source, sections)
        for src in range(3):
            if rnd.random() < 0.5:
                speeds[src] = max(0.0, speeds[src] + rnd.gauss(0.0, 0.05))
                yield f.speed(src, None if src and rnd.random() < 0.02 else speeds[src])
        if step >= silent_until:
            for row in range(1, 5):
                if rnd.random() < 0.8:
                    flow = max(0.0, target * rnd.gauss(1.0, 0.06)
                               * (4.0 if rnd.random() < 0.01 else 1.0)
                               * (wrong_gain if row == wrong_row else 1.0))
                    state = 0 if rnd.random() < 0.03 else 2 if rnd.random() < 0.02 else 1
                    diag = 1 if rnd.random() < 0.03 else 0
                    if row == wrong_row:                 # its fault shows no flag
                        state, diag = 1, 0
                    yield f.row(row, flow, state, diag)
        if rnd.random() < 0.02:                          # an undefined row, a short frame
            yield can.Message(arbitration_id=0x1B0, is_extended_id=False,
                              data=bytes([7, 1, 2, 0x40, 0, 0, 0, 0]))
        if rnd.random() < 0.02:
            yield can.Message(arbitration_id=0x312, is_extended_id=False, data=bytes([1, 2]))
        yield None


def _line(kind: str, msg: can.Message) -> str:
    return f"{kind} {msg.arbitration_id:x} {'x' if msg.is_extended_id else 's'} " \
           f"{bytes(msg.data).hex()}"


def write(path: Path, params: dict[str, Any]) -> None:
    ctl = DbcFlowController(RC400_DATABASE, RC400_SIGNALS, params)
    lines = [f"# {path.name}: written by firmware/byo/tests/make_vectors.py (seed {SEED}) "
             "from reference_controllers/fertilizer/dbc_adapter.py; do not edit",
             "params " + " ".join(f"{k}={v}" for k, v in params.items()),
             "boot", *(_line("out", m) for m in ctl.on_start())]
    for msg in events(random.Random(SEED)):
        if msg is None:
            lines.append("step")
            lines.extend(_line("out", m) for m in ctl.step())
        else:
            lines.append(_line("in", msg))
            lines.extend(_line("out", m) for m in ctl.on_frame(msg))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="directory to write the vector files into")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, params in VECTORS.items():
        write(args.out / name, params)
    return 0


if __name__ == "__main__":
    sys.exit(main())
