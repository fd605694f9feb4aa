"""Lockstep steps per second against a DUT client that keeps Nagle on, and one that does not.

Issue 31 item 2: a socketcand client without ``TCP_NODELAY`` that answers SYNC with three small
writes (status, heartbeat, command) ran 25 times slower in lockstep: each write after the
first waited for the ACK of the one before, and the bus, having nothing to send back, delayed
that ACK (~40 ms on Linux). The bus now acknowledges at once after each read
(``TCP_QUICKACK``, :mod:`hil.softbus.transport`).

The rig side is what a lockstep run uses: an embedded :class:`~hil.softbus.SoftwareBus`, the
rig's :meth:`~hil.softbus.SoftwareBus.local_bus` (busy polling as the runner's) and a
:class:`~hil.clock.SyncBarrier` awaiting the command frame. The DUT is a child process
speaking socketcand over a plain socket, with or without ``TCP_NODELAY``; it answers every
SYNC with three frames in three ``send`` calls, the command last. Both cases run in turn,
``ROUNDS`` times each; the median steps per second of each and their ratio are printed (the
target: Nagle within 1.5x of NODELAY). Nothing is asserted on time::

    python benchmarks/bench_nagle.py [STEPS] [ROUNDS]
"""

from __future__ import annotations

import socket
import statistics
import subprocess
import sys
import time

import can

from hil.clock import SyncBarrier
from hil.rig.runner import LOCKSTEP_BUSY_POLL_US
from hil.softbus import SoftwareBus

COMMAND_ID = 0x220
#: the DUT's answer to each SYNC, in this order, one ``send`` each
ANSWER = (b"< send 1a0 8 00 00 00 00 00 00 00 00 >", b"< send 701 1 05 >",
          b"< send 220 2 00 00 >")

CLIENT = r"""
import socket, sys
port, nodelay = int(sys.argv[1]), sys.argv[2] == "1"
answer = [a.encode() for a in sys.argv[3:]]
sock = socket.create_connection(("127.0.0.1", port))
if nodelay:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
buf = b""
def expect(word):
    global buf
    while word not in buf:
        data = sock.recv(4096)
        if not data:
            sys.exit(0)
        buf += data
    buf = buf[buf.index(word) + len(word):]
expect(b"< hi >")
sock.sendall(b"< open can0 >"); expect(b"< ok >")
sock.sendall(b"< rawmode >"); expect(b"< ok >")
print("ready", flush=True)
while True:
    expect(b"< frame 080 ")
    for frame in answer:
        sock.sendall(frame)
"""


def steps_per_second(nodelay: bool, steps: int) -> float:
    """Run ``steps`` lockstep steps against a fresh client; return steps per wall second."""
    with SoftwareBus(port=0) as bus:
        rig = bus.local_bus(busy_poll_us=LOCKSTEP_BUSY_POLL_US)
        child = subprocess.Popen([sys.executable, "-c", CLIENT, str(bus.port),
                                  "1" if nodelay else "0", *(a.decode() for a in ANSWER)],
                                 stdout=subprocess.PIPE, text=True)
        try:
            assert child.stdout is not None and child.stdout.readline().strip() == "ready"
            received: list[can.Message] = []
            barrier = SyncBarrier(rig, period_ticks=1, await_ids={COMMAND_ID},
                                  dispatch=received.append, timeout_s=5.0)
            barrier.complete(0, 0.0, wait=True)       # warm-up step
            start = time.perf_counter()
            for k in range(1, steps + 1):
                barrier.complete(k, k * 0.01, wait=True)
            wall = time.perf_counter() - start
            # every step's three frames arrived (the last step's may still be on the way)
            if len(received) < 3 * steps:
                raise AssertionError(f"{len(received)} frames for {steps} steps")
        finally:
            child.kill()
            child.wait()
            rig.shutdown()
    return steps / wall


def main(argv: list[str]) -> None:
    steps = int(argv[0]) if argv else 300
    rounds = int(argv[1]) if len(argv) > 1 else 3
    figures: dict[str, list[float]] = {"NODELAY": [], "Nagle": []}
    for _ in range(rounds):
        figures["NODELAY"].append(steps_per_second(True, steps))
        figures["Nagle"].append(steps_per_second(False, steps))
    med = {name: statistics.median(v) for name, v in figures.items()}
    for name, values in figures.items():
        print(f"{name:8s} {med[name]:9.0f} steps/s (median of {rounds}; "
              f"{min(values):.0f}-{max(values):.0f}), {1e6 / med[name]:8.0f} us/step")
    print(f"Nagle takes {med['NODELAY'] / med['Nagle']:.2f}x the NODELAY client's time "
          f"per step (target <= 1.5x); {socket.gethostname()}, {steps} steps per round")


if __name__ == "__main__":
    main(sys.argv[1:])
