"""The VT status period and the TECU's 100 ms in real time while a big pool is uploaded, parsed,
validated and drawn (issue 39 / the VT under a hostile peer: "VT status keeps its 1 s period
within a stated bound while a 100 kB+ pool is parsed").

The rig's side is what ``hil isobus serve --vt`` runs: the tractor (TECU and TC) and the VT with
its screens drawn, one network, driven in real time (:func:`hil.isobus.wire.drive`) on a
python-can virtual bus; an implement on a thread of its own uploads a pool of each size asked
for (:func:`hil.isobus.vt.samples.large_pool`) over ETP. The script prints the worst gap between
two VT status messages and between two TECU wheel-based speed messages, over the whole run and
within a second of the pool's activation, with the parse and validation time alone::

    nice python benchmarks/bench_vt_status_under_parse.py 100000 300000
"""

from __future__ import annotations

import itertools
import sys
import threading
import time
from pathlib import Path

import can

from hil.bus.registry import open_bus
from hil.isobus.can_id import decode_id
from hil.isobus.field import load_field
from hil.isobus.network import IsobusNetwork
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt.attach import attach_vt
from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, IMPLEMENT_NAME
from hil.isobus.vt.client import VtClient
from hil.isobus.vt.messages import VT_TO_ECU_PGN, Function
from hil.isobus.vt.pool import ObjectPool
from hil.isobus.vt.samples import large_pool
from hil.isobus.wire import drive
from hil.rig.device import Device

FIELD = (Path(__file__).resolve().parents[1] / "plant_emulators" / "fertilizer" / "fields"
         / "field-rect.geojson")


class Stamped(Device):
    """The rig's network, its sent frames stamped with the wall clock."""

    def __init__(self, inner: IsobusNetwork) -> None:
        self.inner = inner
        self.name = inner.name
        self.sent: list[tuple[float, can.Message]] = []

    def next_due(self, time_s: float) -> float:
        return self.inner.next_due(time_s)

    def emit(self, time_s: float) -> list[can.Message]:
        frames = self.inner.emit(time_s)
        now = time.monotonic()
        self.sent += [(now, f) for f in frames]
        return frames

    def accepts(self, msg: can.Message) -> bool:
        return self.inner.accepts(msg)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        frames = self.inner.on_frame(msg, time_s)
        now = time.monotonic()
        self.sent += [(now, f) for f in frames]
        return frames


def _gaps(times: list[float]) -> list[float]:
    return [b - a for a, b in itertools.pairwise(times)]


def run(size: int) -> None:
    data = large_pool(size).to_bytes()
    t0 = time.perf_counter()
    ObjectPool.from_transfers([data], 4)
    parse_s = time.perf_counter() - t0
    tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=1000.0))
    attached = attach_vt(tractor.network, console=None)
    rig = Stamped(tractor.network)
    implement = IsobusNetwork(name="implement")
    cf = implement.add(IMPLEMENT_NAME, IMPLEMENT_ADDRESS, "implement")
    client = VtClient(cf, [data])
    cf.run(client)
    channel = f"vt-status-{size}"
    rig_bus, implement_bus = open_bus(f"virtual:{channel}"), open_bus(f"virtual:{channel}")
    vt = attached.vt
    done = threading.Event()

    def run_rig() -> None:
        now = drive(rig, rig_bus, 600.0, until=lambda: vt.active_working_set is not None)
        drive(rig, rig_bus, 3.0, start_s=now)       # the screen drawn, 3 s more
        done.set()

    thread = threading.Thread(target=run_rig)
    start = time.monotonic()
    thread.start()
    try:
        drive(implement, implement_bus, 610.0, until=done.is_set)
    finally:
        thread.join()
        rig_bus.shutdown()
        implement_bus.shutdown()
    status, tecu = [], []
    for t, f in rig.sent:
        fid = decode_id(f.arbitration_id)
        if fid.pgn == VT_TO_ECU_PGN and f.data[0] == Function.VT_STATUS:
            status.append(t)
        elif fid.pgn == PGN_WHEEL_BASED_SPEED:
            tecu.append(t)
    activated = next(e.time_s for e in vt.events if e.kind == "activated")
    act_wall = start + activated
    near = [b - a for a, b in itertools.pairwise(status) if b > act_wall - 1.5
            and a < act_wall + 1.5]
    near_tecu = [b - a for a, b in itertools.pairwise(tecu) if b > act_wall - 0.5
                 and a < act_wall + 0.5]
    print(f"pool {len(data):,} bytes: parse + validate alone {parse_s * 1000:.0f} ms; upload "
          f"{activated:.1f} s; VT status gaps: worst {max(_gaps(status)) * 1000:.0f} ms "
          f"over the run, {max(near) * 1000:.0f} ms around the activation; TECU gaps: worst "
          f"{max(_gaps(tecu)) * 1000:.0f} ms over the run, {max(near_tecu) * 1000:.0f} ms "
          f"around the activation; screens drawn {attached.recorder.drawn}")


if __name__ == "__main__":
    for arg in sys.argv[1:] or ["100000"]:
        run(int(arg))
