"""A DUT process that works, then stops in a chosen way: the dead-DUT tests' controller.

usage: dying_dut.py HOW:N   (bus spec from AGRIHIL_BUS)

It sends its boot-up frame, answers the first N SYNCs with the fertilizer rig's command frame
0x220, then at SYNC N+1: ``segv`` kills itself with SIGSEGV, ``exit0`` / ``exit3`` exit with
that status, ``raise`` raises (Python's exit status 1), ``hang`` stays alive and silent,
``child`` starts a helper in a session of its own (which sleeps) and keeps answering.
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
    how, _, count = sys.argv[1].partition(":")
    limit = int(count or 0)
    bus = open_bus(os.environ["AGRIHIL_BUS"])
    bus.send(can.Message(arbitration_id=0x710, data=[0x00], is_extended_id=False))
    if how == "child":
        helper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                                  start_new_session=True)
        print(f"helper {helper.pid}", flush=True)
    print(f"pid {os.getpid()}", flush=True)
    print("ready", flush=True)
    syncs = 0
    while True:
        msg = bus.recv(0.05)
        if msg is None or msg.arbitration_id != 0x080:
            continue
        syncs += 1
        if syncs > limit and how != "child":
            print(f"dying_dut: {how} at SYNC {syncs}", file=sys.stderr, flush=True)
            if how == "segv":
                os.kill(os.getpid(), signal.SIGSEGV)
            if how in ("exit0", "exit3"):
                return int(how[-1])
            if how == "raise":
                raise RuntimeError("simulated controller bug")
            if how == "hang":
                while True:
                    time.sleep(1)
        bus.send(can.Message(arbitration_id=0x220, data=[0, 0, 0, 0], is_extended_id=False))


if __name__ == "__main__":
    sys.exit(main())
