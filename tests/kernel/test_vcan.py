"""Kernel SocketCAN inside the guest: two processes over vcan0, and the errors users hit.

Runs inside the user-mode Linux guest (``kernel_can``); see ``tests/kernel/test_guest.py``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.bus import open_bus
from hil.bus.transports import SOCKETCAN_RCVBUF
from hil.errors import BusError
from tests.kernel.conftest import ROOT, VCAN, hil

pytestmark = pytest.mark.kernel_can

PEER = ROOT / "tests" / "helpers" / "softbus_peer.py"
COUNT = 10_000
DAEMON = "dut_profiles/fertilizer-piecewise-pid-daemon.toml"


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


@pytest.fixture
def vcan_down() -> Iterator[str]:
    """A second vcan interface, created and left down."""
    name = "vcan9"
    _ip("link", "add", "dev", name, "type", "vcan")
    try:
        yield name
    finally:
        _ip("link", "del", "dev", name)


def test_ten_thousand_frames_each_way_between_processes_none_lost_in_order() -> None:
    spec = f"socketcan:{VCAN}"
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
        results = [json.loads(peer.communicate(timeout=300)[0].strip().splitlines()[-1])
                   for peer in peers]
    finally:
        for peer in peers:
            if peer.poll() is None:
                peer.kill()
    for result in results:
        assert result["received"] == COUNT, result
        assert result["in_order"], result
    rate = 2 * COUNT / max(r["elapsed_s"] for r in results)
    print(f"\nvcan cross-process: {2 * COUNT} frames, {rate:,.0f} frames/s")


def test_the_receive_buffer_is_raised() -> None:
    import socket

    bus = open_bus(f"socketcan:{VCAN}")
    try:
        size = bus.socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)  # type: ignore[attr-defined]
    finally:
        bus.shutdown()
    # the kernel reports twice the size asked for (its bookkeeping); the default is ~208 KiB
    assert size >= SOCKETCAN_RCVBUF


def test_open_refuses_a_missing_a_down_and_a_non_can_interface(vcan_down: str) -> None:
    with pytest.raises(BusError, match=r"no network interface .nocan7.*ip link add"):
        open_bus("socketcan:nocan7")
    with pytest.raises(BusError, match=f"{vcan_down}: the interface is down.*ip link set up"):
        open_bus(f"socketcan:{vcan_down}")
    with pytest.raises(BusError, match="'lo' is not a CAN interface"):
        open_bus("socketcan:lo")


@pytest.mark.parametrize("problem", ["missing", "down"])
def test_hil_run_on_a_bad_interface_is_a_clear_setup_error(problem: str, vcan_down: str,
                                                           tmp_path: Path) -> None:
    iface = "nocan7" if problem == "missing" else vcan_down
    done = hil("run", "--dut", DAEMON, "--scenario", "bench-step-23",
               "--bus", f"socketcan:{iface}", "--out", str(tmp_path / "run"), timeout=120)
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("hil: error")]
    assert len(lines) == 1, done.stderr
    assert f"socketcan:{iface}" in lines[0]
    assert ("no network interface" if problem == "missing" else "is down") in lines[0]


@pytest.mark.parametrize("problem", ["missing", "down"])
def test_firmware_on_a_bad_interface_says_which_and_why(problem: str, vcan_down: str,
                                                        firmware_build: Path) -> None:
    iface = "nocan7" if problem == "missing" else vcan_down
    done = subprocess.run([str(firmware_build / "agrihil-fertilizer-fw"), "--bus",
                           f"socketcan:{iface}", "--sync"], capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 1, done
    assert f"socketcan:{iface}" in done.stderr
    assert ("no such CAN interface" if problem == "missing" else "is down") in done.stderr
