"""Both reference DUTs, the Python daemon and the C firmware, exit non-zero saying why when
their bus connection closes (issue #22.4).

A DUT orphaned by SIGKILL of ``hil run`` (whose embedded software bus died with it) spun at
~80 % of a core forever: python-can's socketcand client ignores the server's end of stream.
Here the bus runs in its own process and is killed with SIGKILL, as it is then.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.bus import open_bus
from reference_controllers.daemon import bus_spec_for_daemon

ROOT = Path(__file__).resolve().parents[2]
SPEC = re.compile(rb"spec (socketcand:[^\s;]+)")


@pytest.fixture
def bus_process() -> Iterator[tuple[subprocess.Popen[bytes], str]]:
    """``hil bus serve --port 0`` in its own process, and its socketcand spec."""
    proc = subprocess.Popen([sys.executable, "-m", "hil", "bus", "serve", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        assert proc.stdout is not None
        spec = None
        while spec is None:
            line = proc.stdout.readline()
            if not line:
                break
            found = SPEC.search(line)
            spec = found.group(1).decode() if found else None
        assert spec is not None, "hil bus serve printed no spec"
        yield proc, spec
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()


def _kill_bus_and_wait(bus_proc: subprocess.Popen[bytes], spec: str, argv: list[str],
                       bootup_id: int, env: dict[str, str]) -> tuple[int | None, str]:
    """Start ``argv`` on the bus, see its boot-up, SIGKILL the bus; (exit status within
    10 s or None, stderr)."""
    listener = open_bus(spec)
    dut = subprocess.Popen(argv, cwd=ROOT, env=env, stdin=subprocess.DEVNULL,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            msg = listener.recv(0.1)
            if msg is not None and msg.arbitration_id == bootup_id:
                break
            assert dut.poll() is None, "the DUT exited before its boot-up"
        else:
            raise AssertionError(f"no boot-up 0x{bootup_id:X}")
        listener.shutdown()
        bus_proc.send_signal(signal.SIGKILL)
        bus_proc.wait(5)
        try:
            code: int | None = dut.wait(10.0)
        except subprocess.TimeoutExpired:
            code = None
    finally:
        if dut.poll() is None:
            dut.kill()
            dut.wait(5)
    assert dut.stderr is not None
    stderr = dut.stderr.read().decode(errors="replace")
    dut.stderr.close()
    return code, stderr


def _python_env() -> dict[str, str]:
    path = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{path}" if path else str(ROOT)}


@pytest.mark.parametrize(("controller", "bootup_id", "timing"), [
    ("fertilizer-piecewise-pid", 0x710, "--sync"),
    ("fertilizer-piecewise-pid", 0x710, "--period-ms=100"),
    ("sowing-depth-fuzzy-pid", 0x701, "--sync"),
])
def test_daemon_exits_1_when_its_bus_dies(bus_process, controller: str, bootup_id: int,
                                          timing: str) -> None:
    bus_proc, spec = bus_process
    argv = [sys.executable, "-m", "reference_controllers.daemon", "--controller", controller,
            "--bus", spec, timing]
    code, stderr = _kill_bus_and_wait(bus_proc, spec, argv, bootup_id, _python_env())
    assert code == 1, f"still running 10 s after its bus died (status {code}):\n{stderr}"
    assert "bus failed" in stderr and "closed the connection" in stderr, stderr


@pytest.mark.parametrize(("app", "bootup_id", "timing"), [
    ("agrihil-fertilizer-fw", 0x710, "--sync"),
    ("agrihil-fertilizer-fw", 0x710, "--period-ms=100"),
    ("agrihil-depth-fw", 0x701, "--sync"),
])
def test_firmware_exits_1_when_its_bus_dies(bus_process, firmware_bin: Path, app: str,
                                            bootup_id: int, timing: str) -> None:
    bus_proc, spec = bus_process
    argv = [str(firmware_bin / app), "--bus", spec, timing]
    code, stderr = _kill_bus_and_wait(bus_proc, spec, argv, bootup_id, dict(os.environ))
    assert code == 1, f"still running 10 s after its bus died (status {code}):\n{stderr}"
    assert "bus failure" in stderr and "closed the connection" in stderr, stderr


def test_daemon_socketcand_specs_get_a_client_that_sees_the_end_of_stream() -> None:
    assert bus_spec_for_daemon("socketcand:127.0.0.1:1/can0") == (
        "socketcand:127.0.0.1:1/can0,client=agrihil")
    assert bus_spec_for_daemon("socketcand:127.0.0.1:1,client=python-can") == (
        "socketcand:127.0.0.1:1,client=python-can")          # an explicit choice is kept
    assert bus_spec_for_daemon("virtual:x") == "virtual:x"
