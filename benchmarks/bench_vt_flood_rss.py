"""The VT's memory under a hostile working set's flood: this process's resident set size over
run time (the VT under a hostile peer; the serve's own RSS benchmark is
``bench_serve_flood_rss.py``).

The rig's side is what ``hil isobus serve --vt`` runs (the tractor's TECU and TC and the VT with
its screens drawn, one network), in virtual time on a :class:`~hil.isobus.wire.VirtualWire`
(faster than real time: the flood is the same frames). A claimed working set uploads a pool and
then sends, every second of run time, ``COMMANDS_PER_S`` commands (a value change of an object
its mask does not show, and every tenth one a value it shows), ``STORES_PER_S`` store version
commands under 40 labels (the store keeps 8), and 20 addresses that never claimed send
``STRANGERS_PER_S`` messages. The messages are made as they are sent (nothing of the flood is
prepared in memory). Every ``--every`` seconds of run time the RSS is printed with the VT's
counts; it should rise while the VT's records and the network's frame log fill, then stay
flat. Nothing is asserted::

    nice python benchmarks/bench_vt_flood_rss.py [RUN_SECONDS] [--every S]
        # defaults: 600 s of run time, every 60 s
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import can

from hil.isobus.can_id import make_frame
from hil.isobus.field import load_field
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import GLOBAL_ADDRESS
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt.attach import attach_vt
from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.messages import ECU_TO_VT_PGN, WORKING_SET_MASTER_PGN, Function, pad, u16, u32
from hil.isobus.vt.server import VT_ADDRESS, VtOptions
from hil.isobus.wire import VirtualWire
from hil.rig.device import Device

FIELD = (Path(__file__).resolve().parents[1] / "plant_emulators" / "fertilizer" / "fields"
         / "field-rect.geojson")
PEER = 0x92
PEER_NAME = IsobusName(identity_number=0x92, manufacturer_code=77, function=130, device_class=5)
COMMANDS_PER_S = 1000
STORES_PER_S = 50
STRANGERS_PER_S = 500


def rss_mib() -> float:
    with open("/proc/self/statm", encoding="ascii") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _pool() -> tuple[bytes, int, int]:
    b = PoolBuilder()
    font = b.font()
    shown = b.number_variable(0)
    hidden = b.number_variable(0)
    out = b.output_number(shown, font=font)
    b.data_mask([(b.input_number(hidden, font=font), 0, 0)])
    b.working_set(b.data_mask([(out, 10, 10)]))
    return b.build().to_bytes(), shown, hidden


def _change(object_id: int, value: int) -> bytes:
    return bytes([Function.CHANGE_NUMERIC_VALUE]) + u16(object_id) + b"\xff" + u32(value)


class FloodingWorkingSet:
    """A claimed working set: connects, then floods (made as sent)."""

    def __init__(self, port, pool: bytes, shown: int, hidden: int) -> None:
        self.port, self.pool, self.shown, self.hidden = port, pool, shown, hidden
        self.k = 0
        self.next_s = 0.5
        self.step = 0

    def next_due(self, now_s: float) -> float:
        return self.next_s

    def tick(self, now_s: float) -> None:
        send = lambda data: self.port.send(ECU_TO_VT_PGN, data, VT_ADDRESS, 5)  # noqa: E731
        if self.step == 0:
            self.port.send(WORKING_SET_MASTER_PGN, pad([1]), GLOBAL_ADDRESS, 5)
            send(pad([Function.WORKING_SET_MAINTENANCE, 1, 4]))
            send(bytes([Function.GET_MEMORY, 0xFF]) + u32(len(self.pool)) + b"\xff\xff")
            send(bytes([Function.OBJECT_POOL_TRANSFER]) + self.pool)
            self.step, self.next_s = 1, 2.0
            return
        if self.step == 1:
            send(pad([Function.END_OF_OBJECT_POOL]))
            self.step, self.next_s = 2, 3.0
            return
        while self.next_s <= now_s + 1e-9:
            self.k += 1
            if self.k % COMMANDS_PER_S == 0:
                send(pad([Function.WORKING_SET_MAINTENANCE, 0, 4]))
            target = self.shown if self.k % 10 == 0 else self.hidden
            send(_change(target, self.k % 100))
            if self.k % (COMMANDS_PER_S // STORES_PER_S) == 0:
                label = (b"S%d" % (self.k // (COMMANDS_PER_S // STORES_PER_S) % 40)).ljust(7)
                send(bytes([Function.STORE_VERSION]) + label)
            self.next_s += 1.0 / COMMANDS_PER_S


class Strangers(Device):
    """20 addresses that never claimed, sending VT commands (made as sent)."""

    name = "strangers"

    def __init__(self) -> None:
        self.k = 0
        self.next_s = 3.0

    def next_due(self, time_s: float) -> float:
        return self.next_s

    def emit(self, time_s: float) -> list[can.Message]:
        out = []
        while self.next_s <= time_s + 1e-9:
            self.k += 1
            out.append(make_frame(5, ECU_TO_VT_PGN, 0xA0 + self.k % 20, VT_ADDRESS,
                                  _change(1, self.k % 256)))
            self.next_s += 1.0 / STRANGERS_PER_S
        return out

    def accepts(self, msg: can.Message) -> bool:
        return False

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return []


class Forgetful(VirtualWire):
    """A virtual wire that keeps no frames (the test's record, not the rig's memory)."""

    def _carry(self, sender: int, frames: list[can.Message]) -> None:
        super()._carry(sender, frames)
        self.frames.clear()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_s", nargs="?", type=float, default=600.0)
    parser.add_argument("--every", type=float, default=60.0)
    args = parser.parse_args()
    tractor = Tractor(TractorSetup(load_field(FIELD), drive_after_s=1e6))
    attached = attach_vt(tractor.network, options=VtOptions(store_max_versions_per_name=8),
                         console=None)
    vt = attached.vt
    peer = IsobusNetwork(name="peer", log_frames=100)
    pool, shown, hidden = _pool()
    cf = peer.add(PEER_NAME, PEER, "flooding working set")
    cf.run(FloodingWorkingSet(cf, pool, shown, hidden))
    wire = Forgetful([tractor.network, peer, Strangers()])
    start = time.perf_counter()
    t = 0.0
    print(f"{'run time':>9} {'wall':>7} {'RSS MiB':>8} {'commands':>9} {'rejected':>9} "
          f"{'events kept':>11} {'store':>5} {'screens':>7}")
    while t < args.run_s:
        t = min(args.run_s, t + args.every)
        wire.run_until(t, max_steps=100_000_000)
        print(f"{t:9.0f} {time.perf_counter() - start:7.1f} {rss_mib():8.1f} "
              f"{vt.counts['commands']:9d} {vt.counts['rejected']:9d} {len(vt.events):11d} "
              f"{vt.store.count:5d} {attached.recorder.drawn:7d}", flush=True)


if __name__ == "__main__":
    main()
