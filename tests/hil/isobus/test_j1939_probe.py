"""Probe: a can-j1939 ElectronicControlUnit against our network, in real time.

can-j1939 runs its timers on ``time.time()`` in a thread of its own (see the docstring of
:mod:`hil.isobus.network`), so this is the only way to meet it: both stacks on one python-can
``virtual`` bus, ours driven by :func:`hil.isobus.wire.drive`, for a few seconds each. Address
claim both ways (with contention), a BAM and an RTS/CTS transfer both ways, byte-identical.
"""

from __future__ import annotations

import itertools
import threading
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import can
import j1939
import pytest

from hil.isobus.name import IsobusName
from hil.isobus.network import InternalControlFunction, IsobusNetwork
from hil.isobus.port import Received
from hil.isobus.wire import drive

pytestmark = pytest.mark.realtime

OURS_LOW = IsobusName(identity_number=1, manufacturer_code=5, function=130)
OURS_HIGH_SC = IsobusName(identity_number=9, manufacturer_code=900, function=130,
                          self_configurable=True)
THEIRS_LOW = dict(arbitrary_address_capable=0, industry_group=2, function=131,
                  manufacturer_code=1, identity_number=0)
THEIRS_HIGH_SC = dict(arbitrary_address_capable=1, industry_group=2, function=131,
                      manufacturer_code=1000, identity_number=77)
ADDRESS = 0x90
_counter = itertools.count()


class At:
    """An application that runs actions at given run times (the network's thread)."""

    def __init__(self, actions: list[tuple[float, Callable[[], None]]]) -> None:
        self.actions = sorted(actions, key=lambda a: a[0])

    def next_due(self, now_s: float) -> float:
        return self.actions[0][0] if self.actions else float("inf")

    def tick(self, now_s: float) -> None:
        while self.actions and self.actions[0][0] <= now_s:
            self.actions.pop(0)[1]()


@contextmanager
def bench(theirs: dict, ours: IsobusName) -> Iterator[tuple[IsobusNetwork,
                                                            InternalControlFunction,
                                                            j1939.ControllerApplication,
                                                            can.BusABC]]:
    channel = f"agrihil-j1939-{uuid.uuid4().hex[:8]}-{next(_counter)}"
    bus = can.Bus(interface="virtual", channel=channel)
    ecu = j1939.ElectronicControlUnit()
    ecu.connect(interface="virtual", channel=channel)
    ca = j1939.ControllerApplication(j1939.Name(**theirs), ADDRESS)
    ecu.add_ca(controller_application=ca)
    net = IsobusNetwork()
    cf = net.add(ours, ADDRESS, "ours")
    try:
        yield net, cf, ca, bus
    finally:
        ca.stop()
        ecu.disconnect()
        ecu.stop()
        bus.shutdown()


def test_claim_their_stack_yields_to_our_lower_name() -> None:
    with bench(THEIRS_HIGH_SC, OURS_LOW) as (net, cf, ca, bus):
        ca.start()                                     # claims 0.5 s later
        t = drive(net, bus, 3.0, until=lambda: ca.state == ca.State.NORMAL and cf.address)
        drive(net, bus, 0.3, start_s=t)
        assert cf.address == ADDRESS
        assert ca.state == ca.State.NORMAL and ca.device_address == ADDRESS + 1
        assert net.external() == {ADDRESS + 1: j1939.Name(**THEIRS_HIGH_SC).value}
        assert [e.kind for e in cf.claimer.events][:3] == ["claim", "claimed", "defended"]


def test_claim_our_stack_yields_to_their_lower_name() -> None:
    with bench(THEIRS_LOW, OURS_HIGH_SC) as (net, cf, ca, bus):
        ca.start()
        drive(net, bus, 3.0, until=lambda: cf.address is not None and cf.address != ADDRESS)
        # the first free address of ISO 11783-5's self-configurable range 128-247
        assert cf.address == 128 and ca.device_address == ADDRESS
        assert net.external() == {ADDRESS: j1939.Name(**THEIRS_LOW).value}
        assert [e.kind for e in cf.claimer.events] == ["claim", "claimed", "lost", "moved",
                                                       "claim", "claimed"]


def _received_by_them(ca: j1939.ControllerApplication) -> tuple[list, threading.Event]:
    got: list[tuple[int, int, bytes]] = []
    done = threading.Event()

    def on_message(priority: int, pgn: int, sa: int, timestamp: float, data: bytes) -> None:
        if pgn in (0xFF10, 0xEF00):
            got.append((pgn, sa, bytes(data)))
            done.set()
    ca.subscribe(on_message)
    return got, done


@pytest.mark.parametrize(("pgn", "destination", "size"), [(0xFF10, 0xFF, 100),
                                                          (0xEF00, ADDRESS, 500)])
def test_transfer_from_us_to_their_stack(pgn: int, destination: int, size: int) -> None:
    data = bytes((i * 13 + 5) & 0xFF for i in range(size))
    with bench(THEIRS_LOW, OURS_HIGH_SC) as (net, cf, ca, bus):
        got, done = _received_by_them(ca)
        ca.start()
        t = drive(net, bus, 3.0, until=lambda: cf.address is not None and
                  ca.state == ca.State.NORMAL)
        cf.run(At([(t, lambda: cf.send(pgn, data, destination=destination))]))
        drive(net, bus, 5.0, until=done.is_set, start_s=t)
        assert got == [(pgn, cf.address, data)]
        assert {e.kind for e in net.transport.events} == {"complete"}


@pytest.mark.parametrize(("pgn", "broadcast", "size"), [(0xFF10, True, 100),
                                                        (0xEF00, False, 500)])
def test_transfer_from_their_stack_to_us(pgn: int, broadcast: bool, size: int) -> None:
    data = bytes((i * 7 + 1) & 0xFF for i in range(size))
    got: list[Received] = []
    with bench(THEIRS_LOW, OURS_HIGH_SC) as (net, cf, ca, bus):
        cf.subscribe(pgn, got.append)
        ca.start()
        t = drive(net, bus, 3.0, until=lambda: cf.address is not None and
                  ca.state == ca.State.NORMAL)
        assert cf.address is not None
        pf, ps = pgn >> 8, (pgn & 0xFF) if broadcast else cf.address
        cf.run(At([(t, lambda: ca.send_pgn(0, pf, ps, 6, list(data)))]))
        drive(net, bus, 5.0, until=lambda: bool(got), start_s=t)
        assert [(m.pgn, m.source, m.data) for m in got] == [(pgn, ADDRESS, data)]
        assert got[0].destination == (0xFF if broadcast else cf.address)
