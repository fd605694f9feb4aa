"""Options are checked before anything runs: exit 2, one line, no traceback, nothing written,
never blamed on the DUT (issues #22.8, #18's known failures, #20.2)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.cli.main import main

ROOT = Path(__file__).resolve().parents[3]
DAEMON = str(ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml")
FIRMWARE = str(ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml")

SCENARIO = '''
name = "{name}"
description = "test"
rig = "fertilizer"
duration_s = {duration}
seed = 1

[initial]
enable = 1.0

[[events]]
at_s = {event_at}
set = {{ enable = 0.0 }}
'''


def _one_line_exit_2(capsys: pytest.CaptureFixture[str], argv: list[str], *words: str) -> str:
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


@pytest.mark.parametrize(("extra", "words"), [
    (["--seed", "-1"], ["--seed", "-1 is not a seed"]),
    (["--seed", str(2**64)], ["--seed"]),
    (["--step-timeout", "-1"], ["--step-timeout"]),
    (["--step-timeout", "nan"], ["--step-timeout", "nan"]),
    (["--step-timeout", "inf"], ["--step-timeout"]),
    (["--step-timeout", "0"], ["--step-timeout"]),
    (["--bus", "virtual"], ["--bus", "softbus", "socketcand"]),
])
def test_hil_run_refuses_bad_options(capsys, tmp_path: Path, extra: list[str],
                                     words: list[str]) -> None:
    out = tmp_path / "out"
    _one_line_exit_2(capsys, ["run", "--dut", DAEMON, "--scenario", "bench-step-23",
                              "--out", str(out), *extra], *words)
    assert not out.exists()                      # nothing ran, nothing written


def test_hil_run_refuses_an_out_that_is_a_file_or_cannot_be_made(capsys, tmp_path) -> None:
    file = tmp_path / "a-file"
    file.write_text("keep me")
    _one_line_exit_2(capsys, ["run", "--dut", DAEMON, "--scenario", "bench-step-23",
                              "--out", str(file)], "--out", "not a directory")
    _one_line_exit_2(capsys, ["run", "--dut", DAEMON, "--scenario", "bench-step-23",
                              "--out", str(file / "below")], "--out", "cannot create")
    assert file.read_text() == "keep me"


@pytest.mark.parametrize(("duration", "event_at", "words"), [
    ("inf", "1.0", ["duration_s"]),
    ("5.0", "7.5", ["events[0].at_s", "after the end of the run"]),
])
def test_hil_run_refuses_a_scenario_that_cannot_run(capsys, tmp_path: Path, duration: str,
                                                    event_at: str, words: list[str]) -> None:
    scenario = tmp_path / "bad.toml"
    scenario.write_text(SCENARIO.format(name="bad", duration=duration, event_at=event_at))
    _one_line_exit_2(capsys, ["run", "--dut", "builtin:pi", "--rig", "fertilizer",
                              "--scenario", str(scenario), "--out", str(tmp_path / "o")],
                     *words)


@pytest.mark.parametrize(("argv", "words"), [
    (["--suite", "nonsense"], ["nonsense", "fast", "full", "robustness", "busload", "all"]),
    (["--seed", "-1000"], ["--seed"]),
    (["--bus", "virtual"], ["--bus", "daemon", "softbus"]),
])
def test_hil_qualify_refuses_bad_options(capsys, tmp_path: Path, argv: list[str],
                                         words: list[str]) -> None:
    out = tmp_path / "qual"
    _one_line_exit_2(capsys, ["qualify", DAEMON, "--out", str(out), *argv], *words)
    assert not out.exists()


def test_a_firmware_dut_on_an_in_process_bus_is_refused_naming_the_buses(capsys,
                                                                         tmp_path) -> None:
    for bus in ("virtual", "inline"):
        _one_line_exit_2(capsys, ["qualify", FIRMWARE, "--bus", bus, "--out",
                                  str(tmp_path / "q")], "firmware", "softbus", "socketcan")


def test_port_out_of_range_is_one_line(capsys) -> None:
    _one_line_exit_2(capsys, ["bus", "serve", "--port", "99999"], "--port", "0..65535")


def test_gate_refuses_an_unwritable_baseline_before_reading_anything(capsys, tmp_path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    _one_line_exit_2(capsys, ["gate", str(tmp_path / "record.json"), "--baseline",
                              str(blocker / "dir" / "b.json"), "--update-baseline"],
                     "--baseline", "is a file")


def test_an_os_error_from_user_input_is_one_line_not_a_traceback(capsys, tmp_path,
                                                                 monkeypatch) -> None:
    """What a library raises on a bad path (python-can opening --log, say) reaches main() as
    an OSError: one line naming the file, exit 2, not an "internal error"."""
    import argparse

    def opens_a_bad_path(args):
        raise FileNotFoundError(2, "No such file or directory", str(tmp_path / "x.log"))
    monkeypatch.setattr(argparse.ArgumentParser, "parse_args",
                        lambda self, argv=None: argparse.Namespace(
                            func=opens_a_bad_path, debug=False, verbose=0))
    err = _one_line_exit_2(capsys, ["run"], "x.log", "No such file or directory")
    assert "internal error" not in err


def test_a_bug_is_an_internal_error_with_the_debug_hint(capsys, monkeypatch) -> None:
    import argparse

    def bug(args):
        raise KeyError("oops")
    monkeypatch.setattr(argparse.ArgumentParser, "parse_args",
                        lambda self, argv=None: argparse.Namespace(func=bug, debug=False,
                                                                   verbose=0))
    _one_line_exit_2(capsys, ["run"], "internal error", "KeyError", "--debug")


def test_pytest_with_a_process_dut_on_the_virtual_bus_is_a_usage_error(tmp_path) -> None:
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "pytest", str(ROOT / "test_suites" /
                                                               "fertilizer"),
                           "-c", str(ROOT / "test_suites" / "pytest.ini"),
                           "-p", "no:cacheprovider", "--hil-dut", FIRMWARE,
                           "--hil-bus", "virtual", "--hil-report", str(tmp_path / "r")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 4, proc.stdout[-2000:] + proc.stderr[-2000:]   # usage error
    assert "--hil-bus: [--bus] virtual lives inside the rig's process" in proc.stderr
