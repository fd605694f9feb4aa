"""What the software-bus tests share: a frame, draining a bus, a frame's comparable fields."""

from __future__ import annotations

import time

import can


def msg(can_id: int, data: bytes = b"\x01", extended: bool = False) -> can.Message:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=extended)


def drain(bus: can.BusABC, n: int, timeout: float = 5.0, poll_s: float = 0.1
          ) -> list[can.Message]:
    """Up to ``n`` frames from ``bus`` within ``timeout``."""
    out: list[can.Message] = []
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        got = bus.recv(poll_s)
        if got is not None:
            out.append(got)
    return out


def fields(m: can.Message) -> tuple[object, ...]:
    """Everything a client sees of a frame, to compare two clients' views."""
    return (m.arbitration_id, m.is_extended_id, m.is_error_frame, m.dlc,
            bytes(m.data), type(m.data), m.is_rx, m.channel, m.timestamp)
