from __future__ import annotations

import argparse
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


@pytest.mark.parametrize("argv", [
    ["--id", "-1"], ["--id", "0x20000000"], ["--mask", "-1"], ["--mask", "0x40000000"],
    ["--id", "1.5"], ["-p", "1.5"], ["-p", "nan"], ["--count", "-1"], ["--delay", "-0.1"],
    ["--delay", "inf"]])
def test_bus_fault_numbers_out_of_range_are_refused_naming_the_option(
        argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    # before: --id -1 and --mask -1 installed a rule shown as id=0x-1; an id above 29 bits was
    # masked down and matched id 0
    assert main(["bus", "fault", "--port", "1", "add", "drop", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"argument {argv[0]}" in err[0], err
    assert "range" in err[0] or "is not a" in err[0], err


def test_every_numeric_option_has_its_range_in_the_help() -> None:
    """The reference page is generated from these help texts (sphinx-argparse)."""
    from hil.cli.main import build_parser
    from hil.validation import CLI_RANGES

    text = " ".join(" ".join(_all_help(build_parser())).split())   # argparse wraps lines
    for rng in CLI_RANGES.values():
        assert rng.describe() in text, rng


def _all_help(parser: argparse.ArgumentParser) -> list[str]:
    out = [parser.format_help()]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out += _all_help(sub)
    return out
