from __future__ import annotations

import subprocess
import sys

import pytest

from hil.cli.main import main
from hil.softbus import SoftwareBusProcess
from hil.softbus.server import SoftwareBusError


def test_usage_error_exits_2(capsys) -> None:
    assert main(["no-such-command"]) == 2
    assert main(["bus", "serve", "--port", "notaport"]) == 2


def test_setup_error_is_one_line_and_exits_2(capsys) -> None:
    assert main(["bus", "stats", "--port", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: cannot reach the software bus") and "Traceback" not in err


def test_debug_shows_the_traceback() -> None:
    proc = subprocess.run([sys.executable, "-m", "hil", "--debug", "bus", "stats", "--port", "1"],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_serve_refuses_a_public_address() -> None:
    assert main(["bus", "serve", "--host", "0.0.0.0", "--port", "0"]) == 2


def test_fault_and_stats_commands_against_a_running_bus(capsys) -> None:
    with SoftwareBusProcess(port=0) as server:
        port = str(server.port)
        assert main(["bus", "fault", "--port", port, "add", "drop", "--id", "0x181"]) == 0
        assert "< hil ok 1 >" in capsys.readouterr().out
        assert main(["bus", "fault", "--port", port, "list"]) == 0
        assert "drop id=0x181" in capsys.readouterr().out
        assert main(["bus", "fault", "--port", port, "clear"]) == 0
        assert main(["bus", "stats", "--port", port]) == 0
        assert '"frames_in": 0' in capsys.readouterr().out


def test_a_bus_process_that_cannot_start_says_why_and_leaves_nothing_open() -> None:
    with SoftwareBusProcess(port=0) as server:
        second = SoftwareBusProcess(port=server.port)
        with pytest.raises(SoftwareBusError, match="Address already in use"):
            second.start(timeout=10)
        assert second.proc is not None and second.proc.poll() is not None
        assert second.proc.stdout is not None and second.proc.stdout.closed
    assert server.proc is not None and server.proc.stdout is not None
    assert server.proc.poll() is not None and server.proc.stdout.closed
