"""The daemons as real processes on the software bus."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.softbus import SoftwareBus

ROOT = Path(__file__).resolve().parents[2]
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")


def _env() -> dict[str, str]:
    path = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{path}" if path else str(ROOT)}


def daemon_argv(*args: str) -> list[str]:
    return [sys.executable, "-m", "reference_controllers.daemon", *args]


@contextmanager
def running(*args: str) -> Iterator[subprocess.Popen[bytes]]:
    proc = subprocess.Popen(daemon_argv(*args), cwd=ROOT, env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        assert proc.stderr is not None
        proc.stderr.close()


def wait_for(bus: can.BusABC, can_id: int, timeout: float, data: bytes | None = None
             ) -> can.Message:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = bus.recv(0.05)
        if msg is not None and msg.arbitration_id == can_id and (
                data is None or bytes(msg.data) == data):
            return msg
    raise AssertionError(f"no frame 0x{can_id:X} within {timeout} s")


def stop_quickly(proc: subprocess.Popen[bytes]) -> tuple[int, float, str]:
    start = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    code = proc.wait(5)
    assert proc.stderr is not None
    return code, time.monotonic() - start, proc.stderr.read().decode()


def test_daemon_answers_sync_and_exits_on_sigterm(softbus: SoftwareBus) -> None:
    bus = open_bus(softbus.spec())
    try:
        with running("--controller", "fertilizer-piecewise-pid", "--bus", softbus.spec(),
                     "--sync", "--param", "mode=physical") as proc:
            wait_for(bus, 0x710, 20.0, data=b"\x00")            # CANopen boot-up
            bus.send(SYNC)
            command = wait_for(bus, 0x220, 2.0)                  # AnalogOutputCommand
            assert bytes(command.data) == bytes(4)               # no setpoint yet: 0 V
            quiet_until = time.monotonic() + 0.3
            while time.monotonic() < quiet_until:
                msg = bus.recv(0.05)
                assert msg is None or msg.arbitration_id != 0x220
            code, took, stderr = stop_quickly(proc)
        assert code == 0 and took < 2.0, stderr
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and "fertilizer-piecewise-pid" in lines[0], stderr
    finally:
        bus.shutdown()


def test_depth_daemon_free_runs_on_its_own_timer(softbus: SoftwareBus) -> None:
    bus = open_bus(softbus.spec())
    try:
        with running("--controller", "sowing-depth-fuzzy-pid", "--bus", softbus.spec(),
                     "--period-ms", "20", "--param", "kp0=2.0") as proc:
            wait_for(bus, 0x701, 20.0, data=b"\x00")
            start = time.monotonic()
            stamps = []
            while time.monotonic() - start < 0.5:
                msg = bus.recv(0.05)
                if msg is not None and msg.arbitration_id == 0x302:
                    stamps.append(time.monotonic())
            assert 15 <= len(stamps) <= 35                       # ~25 steps in 0.5 s
            code, took, stderr = stop_quickly(proc)
        assert code == 0 and took < 2.0, stderr
    finally:
        bus.shutdown()


@pytest.mark.parametrize(("args", "says"), [
    (["--controller", "fertilizer-open-loop", "--bus", "virtual:x", "--param", "ki1=1"],
     "'ki1'"),
    (["--controller", "sowing-depth-fuzzy-pid", "--bus", "virtual:x", "--param", "kq0=1"],
     "'kq0'"),
    (["--controller", "fertilizer-piecewise-pid", "--bus", "virtual:x", "--param", "mode=pi"],
     "'mode'"),
    (["--controller", "fertilizer-piecewise-pid", "--bus", "nosuch:x"], "nosuch"),
    (["--controller", "fertilizer-piecewise-pid", "--bus", "virtual:x", "--period-ms", "0"],
     "--period-ms"),
    (["--controller", "mystery", "--bus", "virtual:x"], "mystery"),
])
def test_bad_arguments_exit_2_naming_the_problem(args: list[str], says: str) -> None:
    env = {k: v for k, v in _env().items() if k != "AGRIHIL_BUS"}
    proc = subprocess.run(daemon_argv(*args), cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert says in proc.stderr
