"""``hil isobus serve``'s memory under a flood: its resident set size over time (issue 43,
item 5).

The serve (:func:`~hil.isobus.serve.serve`, in this process) runs on a software bus (a child
process). A second child is a peer that connects as an implement (the project's TC client, a
pool of 4 sections), then, for ``FLOOD_SECONDS``, sends ``VALUES_PER_S`` process data values
from its address (each one the TC records, to ``tc.jsonl``) and ``UNSOLICITED_PER_S`` frames
from 20 addresses that never claimed (process data before a working-set master, and TP RTSs),
which the TC answers and logs at a bounded rate. Every ``--every`` seconds this process's RSS is
printed; at the end the summary's counts (values recorded, events by kind, transfers refused)
and what the peer sent. RSS should rise while the serve warms up (imports, the network's frame
log filling) and then stay flat. Nothing is asserted::

    nice python benchmarks/bench_serve_flood_rss.py [FLOOD_SECONDS] [VALUES_PER_S]
        [UNSOLICITED_PER_S] [--every S]         # defaults: 600 5000 500, every 30 s
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIELD = ROOT / "plant_emulators" / "fertilizer" / "fields" / "field-rect.geojson"
NAME = 0xA00C80000AE00099
ADDRESS = 0x86


def rss_mib() -> float:
    with open("/proc/self/statm", encoding="ascii") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def flood(spec: str, seconds: float, values_per_s: float, unsolicited_per_s: float) -> None:
    """The peer: connect, then flood (paced in batches every 10 ms)."""
    from hil.bus.registry import open_bus
    from hil.isobus import ddi
    from hil.isobus import process_data as pd
    from hil.isobus.can_id import make_frame
    from hil.isobus.ddop import ElementType
    from hil.isobus.ddop.samples import section_control_pool
    from hil.isobus.name import IsobusName
    from hil.isobus.network import IsobusNetwork
    from hil.isobus.process_data import Command, ElementCommand
    from hil.isobus.tc_client import TaskControllerClient
    from hil.isobus.tp_messages import PGN_TP_CM, CmFrame, Control, encode_cm
    from hil.isobus.wire import drive

    pool = section_control_pool(sections=4, name=NAME)
    net = IsobusNetwork(name="peer", log_frames=10)
    port = net.add(IsobusName.from_int(NAME), ADDRESS, "implement")
    client = TaskControllerClient(port, pool, on_setpoint=lambda *a: None,
                                  read_value=lambda *a: 0)
    port.run(client)
    bus = open_bus(spec)
    sent = {"values": 0, "unsolicited": 0}
    try:
        t = drive(net, bus, 30.0, until=lambda: client.connected)
        if not client.connected:
            print(json.dumps({"error": "the implement did not connect in 30 s"}))
            return
        product = next(e.element_number for e in pool.elements
                       if e.element_type == ElementType.BIN)
        value = make_frame(5, pd.PROCESS_DATA_PGN, ADDRESS, 0xF7, pd.encode(ElementCommand(
            Command.VALUE, product, ddi.ACTUAL_MASS_PER_AREA_RATE, 24_000)))
        request = pd.encode(pd.RequestStructureLabel())
        rts = encode_cm(CmFrame(Control.RTS, 0xCB00, size=20, packets=3, max_per_cts=255))
        strangers = [make_frame(5, pd.PROCESS_DATA_PGN, 0xA0 + i, 0xF7, request)
                     for i in range(20)] + [make_frame(7, PGN_TP_CM, 0xA0 + i, 0xF7, rts)
                                            for i in range(20)]
        start = time.monotonic()
        owed_v = owed_u = 0.0
        last = start
        k = 0
        while (now := time.monotonic()) - start < seconds:
            owed_v += (now - last) * values_per_s
            owed_u += (now - last) * unsolicited_per_s
            last = now
            for _ in range(int(owed_v)):
                bus.send(value)
            for _ in range(int(owed_u)):
                bus.send(strangers[k % len(strangers)])
                k += 1
            sent["values"] += int(owed_v)
            sent["unsolicited"] += int(owed_u)
            owed_v -= int(owed_v)
            owed_u -= int(owed_u)
            # the client's own traffic (its client task every 2 s keeps the session)
            t = drive(net, bus, 0.01, start_s=t)
    finally:
        bus.shutdown()
    print(json.dumps({"sent": sent, "connected": client.connected}))


def main(argv: list[str]) -> None:
    if argv[:1] == ["--flood"]:
        flood(argv[1], float(argv[2]), float(argv[3]), float(argv[4]))
        return
    every = 30.0
    if "--every" in argv:
        i = argv.index("--every")
        every = float(argv[i + 1])
        del argv[i:i + 2]
    seconds = float(argv[0]) if argv else 600.0
    values_per_s = float(argv[1]) if len(argv) > 1 else 5000.0
    unsolicited_per_s = float(argv[2]) if len(argv) > 2 else 500.0

    from hil.isobus.field import load_field
    from hil.isobus.serve import serve
    from hil.isobus.tractor import Tractor, TractorSetup
    from hil.softbus.process import SoftwareBusProcess

    print(f"flood: {seconds:g} s of {values_per_s:g} values/s and {unsolicited_per_s:g} "
          f"unsolicited frames/s; RSS every {every:g} s")
    softbus = SoftwareBusProcess().start()
    samples: list[tuple[float, float]] = []
    stop = threading.Event()
    t0 = time.monotonic()

    def sample() -> None:
        while not stop.wait(every if samples else 0.0):
            samples.append((time.monotonic() - t0, rss_mib()))
            print(f"{samples[-1][0]:7.0f} s  RSS {samples[-1][1]:7.1f} MiB", flush=True)

    sampler = threading.Thread(target=sample, name="rss-sampler")
    sampler.start()
    try:
        spec = softbus.spec() + ",client=agrihil"
        peer = subprocess.Popen([sys.executable, __file__, "--flood", spec, str(seconds),
                                 str(values_per_s), str(unsolicited_per_s)],
                                stdout=subprocess.PIPE, text=True)
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=1e6))
            serve(tractor, spec, out, duration_s=seconds + 40.0, console=None)
            answer, _ = peer.communicate(timeout=120)
            summary = json.loads((out / "summary.json").read_text())
            tc_jsonl = (out / "tc.jsonl").stat().st_size
    finally:
        stop.set()
        sampler.join()
        softbus.stop()
    print(f"peer: {answer.strip()}")
    print(f"serve: {summary['values']:,} values recorded ({tc_jsonl / 2**20:.0f} MiB of "
          f"tc.jsonl), {summary['frames']:,} frames, events {summary['event_counts']}, "
          f"transfers {summary['transfers']}")
    after_warmup = [r for t, r in samples if t >= 60.0] or [r for _, r in samples]
    print(f"RSS: first {samples[0][1]:.1f} MiB, from 60 s on min {min(after_warmup):.1f} / "
          f"max {max(after_warmup):.1f} MiB, last {samples[-1][1]:.1f} MiB")


if __name__ == "__main__":
    main(sys.argv[1:])
