"""The bus acknowledges every read at once, so a client that keeps Nagle on is not held back.

A client without ``TCP_NODELAY`` holds each small write until the bus has acknowledged the one
before; Linux delays that ACK (~40 ms) when the bus has nothing to send back, which made such a
DUT 25x slower in lockstep (issue 31). The speed is measured in ``benchmarks/bench_nagle.py``;
here, that the transport asks for the immediate ACK after each read, and that a Nagle client's
three writes per SYNC all reach the rig.
"""

from __future__ import annotations

import importlib.util
import socket
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from hil.softbus.loop import EventLoop
from hil.softbus.transport import SocketTransport

ROOT = Path(__file__).resolve().parents[3]
QUICKACK = getattr(socket, "TCP_QUICKACK", 12)


class _RecordingSocket(socket.socket):
    """A TCP socket that remembers the options set on it, in order."""

    options: list[tuple[int, int, Any]]

    def setsockopt(self, level: int, option: int, value: Any, *rest: Any) -> None:  # type: ignore[override]
        self.options.append((level, option, value))
        super().setsockopt(level, option, value, *rest)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="TCP_QUICKACK is Linux's")
def test_every_read_is_acknowledged_at_once() -> None:
    listener = socket.create_server(("127.0.0.1", 0))
    peer = socket.create_connection(listener.getsockname())
    accepted, _ = listener.accept()
    sock = _RecordingSocket(fileno=accepted.detach())
    sock.options = []
    sock.setblocking(False)
    got: list[bytes] = []
    client = SimpleNamespace(server=SimpleNamespace(connections=set()),
                             data_received=got.append, connection_lost=lambda exc: None)
    loop = EventLoop()
    try:
        SocketTransport(sock, loop, client)  # type: ignore[arg-type]
        for n in range(3):
            peer.sendall(b"< send 701 1 05 >")
            while len(got) <= n:
                loop.run_once(1.0, spin=False)
            assert sock.options.count((socket.IPPROTO_TCP, QUICKACK, 1)) == n + 1
    finally:
        loop.close()
        peer.close()
        sock.close()
        listener.close()


def test_a_nagle_client_answers_every_sync_in_full() -> None:
    """The benchmark's Nagle client for a few steps: every answer's three frames arrive (the
    benchmark raises when a step's frames are missing)."""
    spec = importlib.util.spec_from_file_location("bench_nagle",
                                                  ROOT / "benchmarks" / "bench_nagle.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.steps_per_second(False, 20) > 0
