"""A toy DUT process for the process-hygiene tests: it misbehaves on request.

usage: toy_dut.py BEHAVIOUR  (bus spec from AGRIHIL_BUS)
  good        boot-up frame, then answer each SYNC with frame 0x220
  crash       boot-up, then exit 3 after the first SYNC with a message on stderr
  crash-soon  boot-up, then exit 3 after 0.3 s, SYNC or not (a crash in real time)
  hang        boot-up, ignore SIGTERM, never answer
  silent      never sends anything (no boot-up)
  flood       boot-up, then answer each SYNC with 500 frames 0x3F0 before its 0x220 (the
              step-end frame last, so in lockstep every one of them lands in the step it
              answers, however the socket delivers them)
  child       boot-up, start a grandchild that sleeps forever, answer SYNC
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import can

from hil.bus import open_bus


def main() -> int:
    behaviour = sys.argv[1]
    print(f"toy dut {behaviour} starting", flush=True)
    if behaviour == "silent":
        time.sleep(60)
        return 0
    if behaviour == "hang":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    stop = False

    def on_term(signum: int, frame: object) -> None:
        nonlocal stop
        stop = True

    if behaviour != "hang":
        signal.signal(signal.SIGTERM, on_term)
    if behaviour == "child":
        subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    bus = open_bus(os.environ["AGRIHIL_BUS"])
    bus.send(can.Message(arbitration_id=0x710, data=[0x00], is_extended_id=False))
    print("ready", flush=True)
    if behaviour == "crash-soon":
        time.sleep(0.3)
        print("toy dut: simulated crash", file=sys.stderr, flush=True)
        return 3
    while not stop:
        msg = bus.recv(0.05)
        if msg is None or msg.arbitration_id != 0x080:
            continue
        if behaviour == "crash":
            print("toy dut: simulated crash", file=sys.stderr, flush=True)
            return 3
        if behaviour == "hang":
            continue
        if behaviour == "flood":
            for _ in range(500):
                bus.send(can.Message(arbitration_id=0x3F0, data=[0, 0, 0, 0],
                                     is_extended_id=False))
        bus.send(can.Message(arbitration_id=0x220, data=[0, 0, 0, 0], is_extended_id=False))
    bus.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
