"""Shared pieces of the kernel CAN tests: what runs inside the user-mode Linux guest.

Tests marked ``kernel_can`` need kernel SocketCAN with ``vcan0`` up; they run inside the guest
that :file:`scripts/kernel-can.sh` boots (``tests/kernel/test_guest.py`` does that from the
default test run) and are skipped, with the reason, anywhere else.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
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


@contextlib.contextmanager
def bus_server() -> Iterator[str]:
    """``hil bus serve --port 0`` in a process of its own; yields the spec to join."""
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen([sys.executable, "-m", "hil", "bus", "serve", "--port", "0"],
                                cwd=ROOT, stdout=out, stderr=subprocess.DEVNULL, text=True)
        try:
            deadline = time.monotonic() + 30
            match = None
            while match is None and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.05)
                out.seek(0)
                match = re.search(r"spec ([^\s;]+)", out.read())
            assert match, f"hil bus serve did not say where it listens (exit {proc.poll()})"
            yield match.group(1)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@contextlib.contextmanager
def ecu_player(daemon_profile: str, bus: str) -> Iterator[subprocess.Popen[str]]:
    """Play a physical ECU: the reference daemon of ``daemon_profile`` in real time on ``bus``,
    started here and not by the rig (with the profile's parameters and real-time period)."""
    from hil.dut.profile import load_profile

    profile = load_profile(ROOT / "dut_profiles" / f"{daemon_profile}.toml")
    command = list(profile.launch.command)
    controller = command[command.index("--controller") + 1]
    params = [arg for key, value in profile.parameters.items()
              for arg in ("--param", f"{key}={value}")]
    proc = subprocess.Popen([sys.executable, "-m", "reference_controllers.daemon",
                             "--controller", controller, "--bus", bus,
                             *profile.launch.realtime_args, *params],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    try:
        _until_on_the_bus(proc, bus, profile.wiring.heartbeat_id)
        yield proc
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


#: how long an ECU player may take to come up: a watchdog for one that never does, not a
#: budget (in the one-CPU guest, under load, the daemon's imports alone took over 10 s)
ECU_WATCHDOG_S = 300.0


def _until_on_the_bus(proc: subprocess.Popen[str], bus: str, heartbeat_id: int) -> None:
    """Return once the ECU's heartbeat is on ``bus``, as a powered ECU's is before a bench
    starts: the rig's own wait for it (the profile's ``ready_timeout_s``) then measures the
    bench, not how long the player's interpreter took to start."""
    import time

    from hil.bus import open_bus

    listener = open_bus(bus)
    try:
        deadline = time.monotonic() + ECU_WATCHDOG_S
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                raise RuntimeError(f"the ECU player exited {proc.returncode} before its "
                                   f"heartbeat: {proc.stderr.read() if proc.stderr else ''}")
            msg = listener.recv(0.1)
            if msg is not None and msg.arbitration_id == heartbeat_id \
                    and not msg.is_extended_id:
                return
        raise RuntimeError(f"the ECU player sent no heartbeat 0x{heartbeat_id:X} on {bus} "
                           f"within {ECU_WATCHDOG_S:g} s")
    finally:
        listener.shutdown()


def physical_profile(rig: str, tmp_path: Path, ready_timeout_s: float | None = None) -> Path:
    """The shipped physical-ECU profile of ``rig`` (optionally with a shorter heartbeat wait,
    as a copy under ``tmp_path`` with the same file name)."""
    name = "fertilizer-physical-ecu" if rig == "fertilizer" else "sowing-depth-physical-ecu"
    shipped = ROOT / "dut_profiles" / "physical" / f"{name}.toml"
    if ready_timeout_s is None:
        return shipped
    text = re.sub(r"ready_timeout_s = [0-9.]+", f"ready_timeout_s = {ready_timeout_s}",
                  shipped.read_text())
    copy = tmp_path / "profiles" / f"{name}.toml"
    copy.parent.mkdir(parents=True, exist_ok=True)
    copy.write_text(text)
    return copy
