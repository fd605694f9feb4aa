"""The ``.asc`` bus log is placed in time: its trigger block carries the run's start (#20.6)."""

from __future__ import annotations

import datetime as dt
import shutil
import subprocess
from pathlib import Path

import can
import numpy as np
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


def test_the_date_line_is_the_trigger_blocks_date(tmp_path: Path) -> None:
    """The header's ``date`` (time zero of ``timestamps absolute``) is the run's, not when the
    file was opened: can-utils' asc2log places frames from it (issue 31: it put a log whose run
    started in May at the November day the file was written, 197 days later)."""
    _log(tmp_path)
    lines = (tmp_path / "bus.asc").read_text().splitlines()
    assert lines[0] == "date Thu May 14 09:30:15.750 2026"
    assert lines[3] == "Begin Triggerblock Thu May 14 09:30:15.750 2026"
    assert lines[1:3] == ["base hex  timestamps absolute", "internal events logged"]


def test_asc2log_places_the_log_in_time(tmp_path: Path) -> None:
    asc2log = shutil.which("asc2log")
    if asc2log is None:
        pytest.skip("can-utils' asc2log is not installed (Debian: apt-get install can-utils)")
    _log(tmp_path)
    run = subprocess.run([asc2log, "-I", str(tmp_path / "bus.asc")], capture_output=True,
                         text=True, check=True, timeout=30)
    lines = [line for line in run.stdout.split("\n") if line.startswith("(")]
    # seconds and microseconds: can-utils 2020.11 carries a microsecond sum of exactly 10^6
    # into the next second only above it, and prints "(1778751015.1000000)"
    stamps = [int(sec) + int(usec) / 1e6 for sec, usec in
              (line[1:line.index(")")].split(".") for line in lines)]
    assert len(stamps) == 50
    assert lines[0].endswith(" 181#00 R") and lines[-1].endswith(" 181#31 R")
    assert np.allclose(np.diff(stamps), 0.01, atol=2e-6)
    if "Not able to determine original log file date" in run.stderr:
        # asc2log reads a 24-hour date line through setlocale(LC_TIME, "de_DE") and, without
        # that locale, stamps the log with the current time (its stderr says so)
        pytest.skip("asc2log cannot read any ASC date line here: it needs the de_DE locale "
                    "(localedef -i de_DE -f ISO-8859-1 de_DE; scripts/setup.sh makes it with "
                    f"can-utils): {run.stderr.strip()!r}")
    # asc2log's get_date() hands mktime() a struct tm whose tm_isdst strptime() never set
    # (can-utils asc2log.c): depending on what the stack held, the date is an hour early
    offset = stamps[0] - (START + 0.5)
    assert min(abs(offset), abs(offset + 3600.0)) < 1e-3, offset


def test_the_date_line_is_whole_whatever_python_can_wrote(tmp_path: Path, monkeypatch) -> None:
    """python-can writes its own date line with unpadded milliseconds (``14.5`` for 5 ms), so
    its width varies: the new line replaces it whole, with three-digit milliseconds."""
    import can.io.asc

    class _Now(dt.datetime):
        @classmethod
        def now(cls, tz=None):  # type: ignore[no-untyped-def, override]
            return dt.datetime(2026, 11, 27, 6, 7, 8, 5000)          # python-can: "08.5"

    monkeypatch.setattr(can.io.asc, "datetime", _Now)
    start = dt.datetime(2026, 5, 14, 9, 30, 14, 505000).timestamp()  # first frame: 15.005
    _log(tmp_path, start)
    lines = (tmp_path / "bus.asc").read_text().splitlines()
    assert lines[:4] == ["date Thu May 14 09:30:15.005 2026", "base hex  timestamps absolute",
                         "internal events logged",
                         "Begin Triggerblock Thu May 14 09:30:15.005 2026"]
    first = next(iter(can.ASCReader(tmp_path / "bus.asc", relative_timestamp=False)))
    assert first.timestamp == pytest.approx(start + 0.5, abs=1e-3)
