"""Two python-can clients in separate processes: 10,000 frames each way, none lost, in order.

The same test runs over kernel vcan where the kernel has SocketCAN."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil.bus.transports import kernel_has_socketcan
from hil.softbus import SoftwareBusProcess

PEER = Path(__file__).resolve().parents[2] / "helpers" / "softbus_peer.py"
COUNT = 10_000


def _run_peers(spec: str) -> list[dict]:
    peers = [subprocess.Popen([sys.executable, str(PEER), spec, mine, other, str(COUNT)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
             for mine, other in (("0x101", "0x202"), ("0x202", "0x101"))]
    try:
        for peer in peers:
            assert peer.stdout is not None and peer.stdout.readline().strip() == "ready"
        for peer in peers:
            assert peer.stdin is not None
            peer.stdin.write("go\n")
            peer.stdin.flush()
        results = []
        for peer in peers:
            out, _ = peer.communicate(timeout=120)
            results.append(json.loads(out.strip().splitlines()[-1]))
        return results
    finally:
        for peer in peers:
            if peer.poll() is None:
                peer.kill()


def _check(results: list[dict]) -> None:
    for result in results:
        assert result["received"] == COUNT, result
        assert result["in_order"], result
    rate = 2 * COUNT / max(r["elapsed_s"] for r in results)
    print(f"\ncross-process: {2 * COUNT} frames in both directions, {rate:,.0f} frames/s")


def test_software_bus_between_processes() -> None:
    with SoftwareBusProcess(port=0) as server:
        _check(_run_peers(server.spec()))


@pytest.mark.socketcan
def test_vcan_between_processes() -> None:
    ok, why = kernel_has_socketcan()
    if not ok:
        pytest.skip(f"kernel SocketCAN unavailable: {why}")
    iface = os.environ.get("AGRIHIL_VCAN", "vcan0")
    if not Path(f"/sys/class/net/{iface}").exists():
        pytest.skip(f"no {iface}: `ip link add dev {iface} type vcan && ip link set up {iface}`")
    _check(_run_peers(f"socketcan:{iface}"))
