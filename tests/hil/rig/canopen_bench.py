"""A rig CANopen device on python-can's virtual bus, for tests with canopen's master classes.

The device runs in a thread the way the runner drives it (``next_due``/``emit``, ``accepts``/
``on_frame``), with the wall clock since start as its run time; ``advance(t)`` moves the
device's physics up to ``t`` first (the drive's plant, the analog module's timeout check).
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import can
import canopen

from hil.rig.canopen_device import CanopenDevice


class DeviceOnBus:
    """Runs ``device`` on virtual channel ``channel`` until :meth:`stop`."""

    def __init__(self, device: CanopenDevice, channel: str,
                 advance: Callable[[float], None] | None = None) -> None:
        self.device = device
        self.advance = advance
        self.lock = threading.Lock()
        self.bus = can.Bus(interface="virtual", channel=channel)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        t0 = time.monotonic()
        due = self.device.next_due(-1.0)
        while not self._stop.is_set():
            msg = self.bus.recv(0.001)
            t = time.monotonic() - t0
            out: list[can.Message] = []
            with self.lock:
                if self.advance is not None:
                    self.advance(t)
                if msg is not None and self.device.accepts(msg):
                    out += self.device.on_frame(msg, t)
                if t >= due:
                    out += self.device.emit(t)
                    due = self.device.next_due(t)
            for frame in out:
                self.bus.send(frame)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.bus.shutdown()


@contextmanager
def master_and_device(device: CanopenDevice, eds: str, node_cls: type = canopen.RemoteNode,
                      advance: Callable[[float], None] | None = None
                      ) -> Iterator[tuple[canopen.RemoteNode, DeviceOnBus]]:
    """A canopen master network with ``node_cls(device.node_id, eds)`` facing ``device``."""
    channel = f"co-{uuid.uuid4().hex}"
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    node = node_cls(device.node_id, eds)
    network.add_node(node)
    runner = DeviceOnBus(device, channel, advance)
    try:
        yield node, runner
    finally:
        network.sync.stop()
        for pdo in getattr(node, "rpdo", {}).values():
            pdo.stop()
        runner.stop()
        network.disconnect()


def wait_for(condition: Callable[[], object], timeout_s: float = 5.0) -> None:
    """Poll ``condition`` until it is true; fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.005)
