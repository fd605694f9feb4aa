"""Shared pieces of the kernel CAN tests: what runs inside the user-mode Linux guest.

Tests marked ``kernel_can`` need kernel SocketCAN with ``vcan0`` up; they run inside the guest
that :file:`scripts/kernel-can.sh` boots (``tests/kernel/test_guest.py`` does that from the
default test run) and are skipped, with the reason, anywhere else.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import can
import pytest

from hil.bus.transports import kernel_has_socketcan

ROOT = Path(__file__).resolve().parents[2]
VCAN = os.environ.get("AGRIHIL_VCAN", "vcan0")


def vcan_ready() -> tuple[bool, str]:
    """Whether kernel SocketCAN with the test interface is here, and why not."""
    ok, why = kernel_has_socketcan()
    if not ok:
        return False, (f"kernel SocketCAN unavailable ({why}); these tests run inside the "
                       "guest: bash scripts/kernel-can.sh (tests/kernel/test_guest.py runs it)")
    if not Path(f"/sys/class/net/{VCAN}").exists():
        return False, (f"no {VCAN}: `ip link add dev {VCAN} type vcan && ip link set up "
                       f"{VCAN}`, or run them in the guest: bash scripts/kernel-can.sh")
    return True, "ok"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    ok, why = vcan_ready()
    if ok:
        return
    skip = pytest.mark.skip(reason=why)
    for item in items:
        if item.get_closest_marker("kernel_can") is not None:
            item.add_marker(skip)


def hil(*args: str, timeout: float = 600.0,
        env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run the ``hil`` command line as a user does, in a separate process."""
    return subprocess.run([sys.executable, "-m", "hil", *args], cwd=ROOT, text=True,
                          capture_output=True, timeout=timeout,
                          env={**os.environ, **(env or {})})


def read_bus_log(path: Path) -> list[can.Message]:
    """Every frame of a run's ``bus.log`` (can-utils log format), in file order."""
    with can.CanutilsLogReader(str(path)) as reader:
        return list(reader)


@pytest.fixture(scope="session")
def firmware_build() -> Path:
    """The C firmware, built (or found in the build cache) from its profile."""
    from hil.dut.build import ensure_built
    from hil.dut.profile import load_profile

    profile = load_profile(ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml")
    return Path(str(ensure_built(profile)["build_dir"]))
