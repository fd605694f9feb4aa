"""A physical ECU on a real bus: the rig does not start it, it only checks it is there."""

from __future__ import annotations

import time
from typing import Any

from hil.bus import open_bus
from hil.dut.base import DutError, DutRunner
from hil.dut.profile import DutProfile


class PhysicalDut(DutRunner):
    """Waits for the ECU's heartbeat (any NMT state) on start; nothing to stop."""

    def __init__(self, profile: DutProfile) -> None:
        self.profile = profile
        self.name = profile.name
        self.seen_state: int | None = None

    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        heartbeat = self.profile.wiring.heartbeat_id
        timeout = self.profile.launch.ready_timeout_s
        bus = open_bus(bus_spec)
        try:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                msg = bus.recv(0.1)
                if msg is not None and msg.arbitration_id == heartbeat and msg.data:
                    self.seen_state = msg.data[0]
                    return
        finally:
            bus.shutdown()
        raise DutError(f"physical DUT {self.name!r}: no heartbeat 0x{heartbeat:03X} on "
                       f"{bus_spec} within {timeout:g} s: is it powered and wired to this bus?")

    def check(self) -> None:
        return None

    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        return {"name": self.name, "kind": "physical", "nmt_state_at_start": self.seen_state}

    def identity(self) -> dict[str, Any]:
        return self.profile.identity()
