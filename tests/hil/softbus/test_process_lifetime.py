"""The bus process (:class:`SoftwareBusProcess`) dies with its parent (issue #22.4, bus side)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.softbus import SoftwareBusProcess
from hil.softbus.process import die_with_parent

PARENT = """
import sys, time
from hil.softbus import SoftwareBusProcess
bus = SoftwareBusProcess(port=0).start()
print(bus.proc.pid, flush=True)
time.sleep(120)
"""


def _gone(pid: int) -> bool:
    """No such process, or only its zombie left (dead, waiting to be reaped)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return True
    except OSError:  # no /proc: ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        return False
    return state in ("Z", "X")


def _wait_gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if _gone(pid):
            return True
        time.sleep(0.05)
    return _gone(pid)


def test_the_bus_process_stops_when_its_stdin_closes() -> None:
    bus = SoftwareBusProcess(port=0).start()
    try:
        assert bus.proc is not None and bus.proc.stdin is not None
        bus.proc.stdin.close()  # what the kernel does to the pipe when the parent dies
        assert bus.proc.wait(10) == 0  # a clean stop, not a signal
    finally:
        bus.stop()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_the_death_signal_is_asked_for_from_the_main_thread_only() -> None:
    import threading

    assert die_with_parent() is not None
    found: list[object] = []
    worker = threading.Thread(target=lambda: found.append(die_with_parent()))
    worker.start()
    worker.join()
    assert found == [None]  # a worker thread's end would kill the child


def test_a_sigkilled_parent_takes_the_bus_process_with_it() -> None:
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE,
                              text=True)
    child = 0
    try:
        assert parent.stdout is not None
        line = parent.stdout.readline()
        child = int(line)
        assert not _gone(child)
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
        assert _wait_gone(child, 5.0), f"bus process {child} outlived its SIGKILLed parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait(10)
        if child and not _gone(child):
            os.kill(child, signal.SIGKILL)
