"""How long the Task Controller takes to check a device descriptor object pool, and whether the
tractor ECU's 100 ms messages stay on time meanwhile (issue 43, item 4).

Part 1 parses and validates pools whose elements form one parent chain (the worst case of the
rule "every element reaches the device element"): 1,000 to 6,000 elements (13 to 78 kB). The
time per element stays flat: the check is linear in the pool (it was quadratic: 7.4 s for the
6,000-element chain).

Part 2 runs ``hil isobus serve``'s :func:`~hil.isobus.serve.serve` on a software bus (a child
process) and, in another child, an implement (the project's TC client) that transfers a 100 kB
pool (a 4,000-element chain with 12-byte designators and a working width: valid and usable) by
ETP and activates it. From the serve's own ``bus.log`` it prints the largest gap between the
TECU's wheel-based speed messages over the whole serve and while the pool was being checked
(from the transfer's end to the activate response), and how long the check itself took
(parse, validate, the tractor's usable check) on its own. The serve checks pools in a thread of
their own, so the TECU's gap should stay near 100 ms whatever the check takes; without it the
check's time adds to one gap. Nothing is asserted on time::

    python benchmarks/bench_tc_ddop_check.py [SERVE_SECONDS]     # default 25
"""

from __future__ import annotations

import contextlib
import itertools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import can

from hil.isobus.can_id import decode_id
from hil.isobus.ddop import DdopError, ObjectPool
from hil.isobus.ddop.codec import parse_pool
from hil.isobus.ddop.samples import parent_chain_pool
from hil.isobus.tc.server import parse_and_check
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tractor import check_usable

ROOT = Path(__file__).resolve().parents[1]
FIELD = ROOT / "plant_emulators" / "fertilizer" / "fields" / "field-rect.geojson"
NAME = 0xA00C80000AE00077
CLIENT_ADDRESS = 0x86


def big_pool() -> bytes:
    """100 kB, valid and usable by the rig's tractor."""
    return parent_chain_pool(4000, designator=b"x" * 12, width_mm=6000, name=NAME)


def validation_scaling() -> None:
    print("part 1: parse + validate a parent chain (one pass each)")
    print(f"{'elements':>9} {'bytes':>7} {'ms':>8} {'us/element':>11}")
    for n in (1000, 2000, 4000, 6000):
        raw = parent_chain_pool(n)
        best = float("inf")
        for _ in range(3):
            t = time.perf_counter()
            # beyond 4,095 the element numbers break the 12 bits: refused, after the whole check
            with contextlib.suppress(DdopError):
                ObjectPool.from_bytes(raw)
            best = min(best, time.perf_counter() - t)
        print(f"{n:>9} {len(raw):>7} {best * 1000:>8.1f} {best / n * 1e6:>11.1f}")


def client(spec: str, seconds: float) -> None:
    """The implement: the project's TC client with the 100 kB pool, on the software bus."""
    from hil.bus.registry import open_bus
    from hil.isobus.name import IsobusName
    from hil.isobus.network import IsobusNetwork
    from hil.isobus.tc_client import TaskControllerClient
    from hil.isobus.wire import drive

    raw = big_pool()
    pool = ObjectPool(tuple(parse_pool(raw)), 4)
    net = IsobusNetwork(name="implement", log_frames=10)
    port = net.add(IsobusName.from_int(NAME), CLIENT_ADDRESS, "implement")
    tc_client = TaskControllerClient(port, pool, on_setpoint=lambda *a: None,
                                     read_value=lambda *a: 0)
    port.run(tc_client)
    bus = open_bus(spec)
    try:
        drive(net, bus, seconds)
    finally:
        bus.shutdown()
    print(json.dumps({"connected": tc_client.connected, "transfers": tc_client.transfers,
                      "refusal": str(tc_client.refusal) if tc_client.refusal else None}))


def serve_gap(seconds: float) -> None:
    from hil.isobus.field import load_field
    from hil.isobus.serve import serve
    from hil.isobus.tractor import Tractor, TractorSetup
    from hil.softbus.process import SoftwareBusProcess

    raw = big_pool()
    t = time.perf_counter()
    parse_and_check(raw, 4, check_usable)
    check_s = time.perf_counter() - t
    print(f"\npart 2: the serve on a software bus, an implement activating a {len(raw):,}-byte "
          f"pool")
    print(f"the check alone (parse, validate, usable): {check_s * 1000:.0f} ms")
    softbus = SoftwareBusProcess().start()
    try:
        spec = softbus.spec() + ",client=agrihil"
        implement = subprocess.Popen([sys.executable, __file__, "--client", spec, str(seconds)],
                                     stdout=subprocess.PIPE, text=True)
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=3600.0))
            serve(tractor, spec, out, duration_s=seconds, console=None)
            answer, _ = implement.communicate(timeout=60)
            frames = [m for m in can.LogReader(out / "bus.log")
                      if decode_id(m.arbitration_id).pgn == PGN_WHEEL_BASED_SPEED]
            lines = [json.loads(x) for x in (out / "tc.jsonl").read_text().splitlines()]
    finally:
        softbus.stop()
    print(f"implement: {answer.strip()}")
    print("TC events: " + "; ".join(f"{x['t']:.2f} s {x['event']}" for x in lines
                                    if x["kind"] == "event"))
    times = [m.timestamp for m in frames]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    epoch = times[0] - 0.25      # the TECU's first message goes 0.25 s into the run
    transferred = [x["t"] for x in lines if x.get("event") == "pool transferred"]
    done = [x["t"] for x in lines if x.get("event") in ("activated", "refused")]
    print(f"TECU messages: {len(times)}, median gap {statistics.median(gaps) * 1000:.1f} ms, "
          f"worst {max(gaps) * 1000:.1f} ms over the serve")
    if transferred and done:
        a, b = epoch + transferred[-1], epoch + done[-1]
        during = [t1 - t0 for t0, t1 in itertools.pairwise(times) if t1 >= a and t0 <= b]
        print(f"check window {a - epoch:.2f}-{b - epoch:.2f} s of run time "
              f"({(b - a) * 1000:.0f} ms): worst TECU gap {max(during) * 1000:.1f} ms")
    else:
        print("the pool was not transferred and answered within the serve: no check window")


def main(argv: list[str]) -> None:
    if argv[:1] == ["--client"]:
        client(argv[1], float(argv[2]))
        return
    seconds = float(argv[0]) if argv else 25.0
    validation_scaling()
    serve_gap(seconds)


if __name__ == "__main__":
    main(sys.argv[1:])
