"""The ``.asc`` bus log is placed in time: its trigger block carries the run's start (#20.6)."""

from __future__ import annotations

import datetime as dt
import shutil
import subprocess
from pathlib import Path

import can
import pytest

from hil.record import BusLog

START = dt.datetime(2026, 5, 14, 9, 30, 15, 250000).timestamp()


def _log(directory: Path, start: float | None = START) -> BusLog:
    log = BusLog(directory, formats=("asc", "log"), start_epoch_s=start)
    for i in range(50):
        log.write(can.Message(arbitration_id=0x181, is_extended_id=False, data=bytes([i])),
                  0.5 + i * 0.01, rx=True)
    log.close()
    return log


def test_trigger_block_is_dated_with_the_run_start(tmp_path: Path) -> None:
    _log(tmp_path)
    trigger = [line for line in (tmp_path / "bus.asc").read_text().splitlines()
               if line.startswith("Begin Triggerblock")]
    # first frame at run time 0.5 s: 09:30:15.250 + 0.5 s
    assert trigger == ["Begin Triggerblock Thu May 14 09:30:15.750 2026"]


def test_python_can_reads_frames_at_their_wall_clock_time(tmp_path: Path) -> None:
    _log(tmp_path)
    frames = list(can.ASCReader(tmp_path / "bus.asc", relative_timestamp=False))
    assert len(frames) == 50
    for i, frame in enumerate(frames):
        assert frame.timestamp == pytest.approx(START + 0.5 + i * 0.01, abs=2e-3)
    # relative time stamps are unchanged: from the first frame
    relative = [f.timestamp for f in can.ASCReader(tmp_path / "bus.asc")]
    assert relative[0] == 0.0 and relative[-1] == pytest.approx(0.49)


def test_default_start_is_when_the_log_opens(tmp_path: Path) -> None:
    before = dt.datetime.now().timestamp()
    _log(tmp_path, start=None)
    first = next(iter(can.ASCReader(tmp_path / "bus.asc", relative_timestamp=False)))
    assert before + 0.5 - 1.0 <= first.timestamp <= dt.datetime.now().timestamp() + 1.0


def test_asc2log_places_the_log_in_time(tmp_path: Path) -> None:
    asc2log = shutil.which("asc2log")
    if asc2log is None:
        pytest.skip("can-utils' asc2log is not installed (Debian: apt-get install can-utils)")
    _log(tmp_path)
    out = subprocess.run([asc2log, "-I", str(tmp_path / "bus.asc")], capture_output=True,
                         text=True, check=True, timeout=30).stdout.split("\n")
    stamps = [float(line.split(")")[0].lstrip("(")) for line in out if line.startswith("(")]
    assert len(stamps) == 50
    assert stamps[0] == pytest.approx(START + 0.5, abs=1.0)
