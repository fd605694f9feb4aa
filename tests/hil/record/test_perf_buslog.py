"""The bus log's fast text path writes exactly what python-can's writers write.

:class:`BusLog` formats ordinary frames of the candump ``.log`` and Vector ``.asc`` files itself
(batched) and leaves headers, footers and unusual frames to python-can. The reference here is
the plain way: every frame stamped and handed to ``can.Logger`` writers one by one.
"""

from __future__ import annotations

import json
from pathlib import Path

import can
import pytest

import hil.record.buslog as buslog
from hil.record import BusLog, Recorder


def _frames(n: int = 3000) -> list[tuple[can.Message, float, bool]]:
    out = []
    for i in range(n):
        ext = i % 3 == 0
        out.append((can.Message(arbitration_id=(0x18FF2026 + i) if ext else (0x100 + i % 0x700),
                                is_extended_id=ext, data=bytes((i + k) % 256 for k in range(i % 9)),
                                dlc=i % 9), 0.5 + i * 0.001, i % 2 == 0))
    # the unusual ones: before the first time stamp, error, remote, CAN FD, empty, odd times
    out.insert(5, (can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01"), 0.2,
                   True))
    out.insert(9, (can.Message(is_error_frame=True, arbitration_id=0, data=b""), 0.51, True))
    out.insert(15, (can.Message(arbitration_id=0x321, is_extended_id=False,
                                is_remote_frame=True, dlc=4), 0.52, False))
    out.insert(20, (can.Message(arbitration_id=0x222, is_extended_id=False, is_fd=True,
                                data=bytes(range(12))), 0.53, True))
    out.insert(30, (can.Message(arbitration_id=0x80, is_extended_id=False, data=b""),
                    1234.5678905, False))
    out.append((can.Message(arbitration_id=0x80, is_extended_id=False, data=b""), 99999.000001,
                True))
    return out


def _reference(directory: Path, frames, formats=("log", "asc"), channel="can0") -> list[Path]:
    """The previous implementation: python-can's writers, one stamped message at a time
    (without the FD flags, as it always was)."""
    paths = [directory / f"ref.{fmt}" for fmt in formats]
    writers = [can.Logger(p) for p in paths]
    for msg, t, rx in frames:
        stamped = can.Message(timestamp=t, arbitration_id=msg.arbitration_id,
                              is_extended_id=msg.is_extended_id,
                              is_remote_frame=msg.is_remote_frame,
                              is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=msg.data,
                              channel=channel, is_rx=rx)
        for w in writers:
            w.on_message_received(stamped)
    for w in writers:
        w.stop()
    return paths


def _write(directory: Path, frames, formats=("log", "asc"), channel="can0") -> BusLog:
    log = BusLog(directory, formats=formats, channel=channel)
    for msg, t, rx in frames:
        log.write(msg, t, rx=rx)
    log.close()
    return log


def _body(path: Path) -> list[str]:
    lines = path.read_text().splitlines()
    # the .asc header's date line and trigger block are wall-clock dates (python-can dates the
    # trigger block from the first time stamp, 1970 for a run's clock; BusLog from the run's start)
    if path.suffix == ".asc":
        return [line for line in lines[1:] if not line.startswith("Begin Triggerblock")]
    return lines


@pytest.mark.parametrize("channel", ["can0", "vcan1", "3"])
def test_files_are_line_for_line_those_of_python_can(tmp_path: Path, channel: str) -> None:
    frames = _frames()
    ref_log, ref_asc = _reference(tmp_path, frames, channel=channel)
    log = _write(tmp_path, frames, channel=channel)
    assert all(f is not None for f in log._fast)          # the fast path was taken
    assert _body(tmp_path / "bus.log") == _body(ref_log)
    assert _body(tmp_path / "bus.asc") == _body(ref_asc)
    assert log.frames == len(frames)


def test_they_read_back_as_the_same_frames(tmp_path: Path) -> None:
    frames = _frames(1500)
    ref = _reference(tmp_path, frames)
    _write(tmp_path, frames)
    for mine, theirs in zip((tmp_path / "bus.log", tmp_path / "bus.asc"), ref, strict=True):
        a, b = list(can.LogReader(mine)), list(can.LogReader(theirs))
        assert len(a) == len(b) > 1500
        for x, y in zip(a, b, strict=True):
            assert x.equals(y, timestamp_delta=0.0), (x, y)


def test_a_formatter_that_disagrees_with_python_can_is_not_used(tmp_path: Path,
                                                                monkeypatch) -> None:
    def wrong(channel):
        return lambda msg, t, rx: "nonsense\n"

    monkeypatch.setattr(buslog, "_candump_line", wrong)
    frames = _frames(300)
    ref_log, _ = _reference(tmp_path, frames)
    log = _write(tmp_path, frames)
    assert log._fast[0] is None and log._fast[1] is not None
    assert _body(tmp_path / "bus.log") == _body(ref_log)


def test_other_formats_go_through_python_can(tmp_path: Path) -> None:
    frames = [(m, t, rx) for m, t, rx in _frames(200) if not (m.is_fd or m.is_error_frame)]
    log = _write(tmp_path, frames, formats=("log", "csv"))
    assert log._fast[1] is None
    assert len(list(can.LogReader(tmp_path / "bus.csv"))) == len(frames)


def test_pending_lines_are_written_when_the_run_fails(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError), Recorder(tmp_path) as rec:
        for i in range(100):          # fewer than a batch: all still pending at the error
            rec.log_frame(can.Message(arbitration_id=0x181, is_extended_id=False,
                                      data=bytes([i])), i * 0.01, rx=True)
        raise RuntimeError("bench on fire")
    assert json.loads((tmp_path / "record.json").read_text())["verdict"] == "error"
    for name in ("bus.log", "bus.asc"):
        frames = list(can.LogReader(tmp_path / name))
        assert [f.data[0] for f in frames] == list(range(100))
        assert frames[-1].timestamp == pytest.approx(0.99)
