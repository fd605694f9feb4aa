"""Echo peer for latency benchmarks: answers every frame with id+1 and the same data.

usage: python softbus_echo.py SPEC   (prints "ready", echoes until stdin closes)
"""

from __future__ import annotations

import sys
import threading

import can

from hil.bus import open_bus


def main() -> int:
    bus = open_bus(sys.argv[1])
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    print("ready", flush=True)
    while not stop.is_set():
        msg = bus.recv(0.1)
        if msg is not None and not msg.is_error_frame:
            bus.send(can.Message(arbitration_id=(msg.arbitration_id + 1) & 0x7FF,
                                 data=msg.data, is_extended_id=False))
    bus.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
