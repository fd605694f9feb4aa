"""A peer process for cross-process bus tests: sends N numbered frames, receives N from the
other peer, checks none lost and order kept, prints one JSON line of results.

usage: python softbus_peer.py SPEC MY_ID OTHER_ID COUNT
"""

from __future__ import annotations

import json
import sys
import threading
import time

import can

from hil.bus import open_bus


def main() -> int:
    spec, my_id, other_id, count = sys.argv[1], int(sys.argv[2], 0), int(sys.argv[3], 0), \
        int(sys.argv[4])
    bus = open_bus(spec)
    received: list[int] = []
    done = threading.Event()

    def receive() -> None:
        deadline = time.monotonic() + 60
        while len(received) < count and time.monotonic() < deadline:
            msg = bus.recv(1.0)
            if msg is not None and msg.arbitration_id == other_id:
                received.append(int.from_bytes(msg.data[:4], "little"))
        done.set()

    # both peers must be attached before either sends: announce, then wait for the other
    print("ready", flush=True)
    sys.stdin.readline()
    thread = threading.Thread(target=receive)
    thread.start()
    start = time.perf_counter()
    for seq in range(count):
        bus.send(can.Message(arbitration_id=my_id, is_extended_id=False,
                             data=seq.to_bytes(4, "little") + b"\xAA\xBB\xCC\xDD"))
    done.wait(70)
    elapsed = time.perf_counter() - start
    thread.join(5)
    bus.shutdown()
    in_order = received == list(range(len(received)))
    print(json.dumps({"received": len(received), "in_order": in_order,
                      "elapsed_s": elapsed}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
