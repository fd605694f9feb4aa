"""The bus log in standard formats, through python-can's writers.

candump ``.log`` (can-utils, SavvyCAN, ``python -m can.player``) and Vector ``.asc`` (CANoe,
cantools, asammdf) are written side by side by default; any extension python-can knows
(``.blf``, ``.trc``, ``.csv``…) may be asked for.

python-can's writers own the files: they open them, write the headers (the ``.asc`` date and
trigger block), the first frame, the footers, and every frame out of the ordinary (error and
remote frames, CAN FD, a time stamp before the first one). The ordinary frames of the two text
formats, nearly all of a run's frames, are formatted here and handed to the writer's file in
batches, during the run. Why not ``on_message_received`` for those: per-frame cost. It needs a
``can.Message`` copy per frame (to stamp it with the run's time) and spends 5-10 µs per frame
and writer on formatting and bookkeeping, which made the log a sizable part of a lockstep run's
wall time (some 15 % of it on the sowing-depth rig, 44,000 frames a minute); the lines here cost
about 1 µs. They are the writer's own, byte for byte: each format's formatter is checked against
its python-can writer on probe frames when the log is opened, and a writer whose output differs
(another python-can version, say) gets every frame the ordinary way.

What the logs hold: what the rig received (``R``, ``Rx``) and what it sent (``T``, ``Tx``), as
a bus monitor on the rig's interface would have them. A frame of the DUT that a fault kept from
the rig (a cut wire: :meth:`hil.rig.Rig.admits`) was never received and is in neither: it goes
to ``bus-unheard.log`` (:class:`UnheardLog`, candump, the DUT's frames as ``T``: sent by the DUT,
heard by nobody), so that what the DUT said during the cut can still be read.

Time: frames carry the run's clock (seconds from the run's start). The ``.asc`` trigger block
and the header's ``date`` line are dated with the wall-clock time of the first frame (the run's
start plus that frame's run time), not python-can's ``datetime.fromtimestamp(first time
stamp)``, which dated the trigger block 1970, nor the time the file was opened, which dated the
``date`` line: so ``ASCReader(relative_timestamp=False)`` and can-utils ``asc2log`` (which reads
the ``date`` line, where it can parse it: see docs/guide/kernel-can.md) place the log in time.
"""

from __future__ import annotations

import datetime as dt
import io
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import can
from can.io import logger as can_logger
from can.io.asc import ASCWriter
from can.io.canutils import CanutilsLogWriter
from can.util import channel2int

DEFAULT_FORMATS = ("log", "asc")

#: a line formatter: (message, run time minus the writer's start time, rx) → text
_Formatter = Callable[[Any, float, bool], str]


def _candump_line(channel: str) -> _Formatter:
    """Candump ``-L`` lines as ``CanutilsLogWriter.on_message_received`` writes them."""
    if channel.isdigit():
        channel = f"can{channel}"
    prefix = f") {channel} "

    def line(msg: Any, time_s: float, rx: bool) -> str:
        can_id = f"{msg.arbitration_id:08X}" if msg.is_extended_id \
            else f"{msg.arbitration_id:03X}"
        return (f"({time_s:f}{prefix}{can_id}#{msg.data.hex().upper()}"
                f"{' R' if rx else ' T'}\n")

    return line


def _asc_line(channel: int) -> _Formatter:
    """Vector ASC frame lines as ``ASCWriter.on_message_received`` writes them.

    Time stamps are relative.
    """
    def line(msg: Any, time_s: float, rx: bool) -> str:
        can_id = f"{msg.arbitration_id:X}x" if msg.is_extended_id \
            else f"{msg.arbitration_id:X}"
        return (f"{time_s: 9.6f} {channel}  {can_id:<15} {'Rx' if rx else 'Tx':<4} "
                f"d {msg.dlc:x} {msg.data.hex(' ').upper()}\n")

    return line


#: probe frames the formatters are checked on (after a first frame at t = 0)
_PROBES = [
    (can.Message(arbitration_id=0x080, is_extended_id=False, data=b""), 0.0, False),
    (can.Message(arbitration_id=0x181, is_extended_id=False,
                 data=bytes(range(0xF8, 0x100))), 0.001, True),
    (can.Message(arbitration_id=0x0CFE49F0, is_extended_id=True, data=b"\x01\xab"), 12.345678,
     False),
    (can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"\x00" * 4, dlc=4),
     1234.5678905, True),
    (can.Message(arbitration_id=0x1FFFFFFF, is_extended_id=True, data=b"\x10" * 8), 99999.0,
     True),
]

#: (threshold, origin) of a writer that has written its first frame, else None: frames at or
#: after ``threshold`` are written as ``time - origin``; earlier ones (python-can clamps or
#: writes them absolute) go through the writer
_Span = tuple[float, float] | None


class _FastText:
    """Ordinary frames of one python-can text writer, written straight to its file."""

    def __init__(self, writer: Any, formatter: _Formatter,
                 span_of: Callable[[Any], _Span]) -> None:
        self.formatter = formatter
        self.span_of = span_of
        self.write = writer.file.write
        self.span: _Span = None


def _candump_span(writer: CanutilsLogWriter) -> _Span:
    # absolute time stamps; an earlier one is written as the first frame's
    last = writer.last_timestamp
    return None if last is None else (last, 0.0)


def _asc_span(writer: ASCWriter) -> _Span:
    # time stamps relative to the first frame's; earlier ones are written absolute
    return (writer.started, writer.started) if writer.header_written else None


def _fast_text(writer: Any, channel: str) -> _FastText | None:
    """The fast path for ``writer``, if this module reproduces its lines exactly (else None).

    Only text writers qualify; the lines are checked on probe frames through a scratch writer of
    the same class.
    """
    if type(writer) is CanutilsLogWriter:
        formatter, span_of = _candump_line(channel), _candump_span
    elif type(writer) is ASCWriter:
        number = channel2int(channel)
        formatter, span_of = _asc_line(1 if number is None else number + 1), _asc_span
    else:
        return None
    try:
        probe = type(writer)(io.StringIO())
        first, *rest = _PROBES
        probe.on_message_received(_stamped(first[0], first[1], rx=first[2], channel=channel))
        span = span_of(probe)
        if span is None:
            return None
        before = len(probe.file.getvalue())
        expected = []
        for msg, t, rx in rest:
            probe.on_message_received(_stamped(msg, t, rx=rx, channel=channel))
            expected.append(formatter(msg, t - span[1], rx))
        agrees = probe.file.getvalue()[before:] == "".join(expected)
        probe.stop()
    except Exception:
        return None
    if not agrees:
        return None
    return _FastText(writer, formatter, span_of)


def _open_writer(path: Path) -> Any:
    """``can.Logger(path)``, without its entry point scan.

    That function first scans every installed package's entry points for writer plugins (~10 ms
    per call), which can only add suffixes it does not know yet: for a suffix already in its
    table, it returns exactly ``MESSAGE_WRITERS[suffix](file=path)``, which is what is done here
    without the scan.
    """
    writers = getattr(can_logger, "MESSAGE_WRITERS", None)
    suffix = path.suffix.lower()
    if isinstance(writers, dict) and suffix != ".gz" and suffix in writers:
        return writers[suffix](file=path)
    return can.Logger(path)


def _stamped(msg: can.Message, time_s: float, *, rx: bool, channel: str) -> can.Message:
    """``msg`` stamped with the run's time and direction, for python-can's writers.

    As the log always did, a CAN FD frame's FD flags are not carried over.
    """
    return can.Message(timestamp=time_s, arbitration_id=msg.arbitration_id,
                       is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                       is_error_frame=msg.is_error_frame, dlc=msg.dlc, data=msg.data,
                       channel=channel, is_rx=rx)


#: fast-path lines are handed to the files in batches of this many frames (one large write
#: instead of one ``TextIOWrapper.write`` per line and a syscall per 8 KiB)
_BATCH = 1024


def _asc_date(when: dt.datetime) -> str:
    """An ASC header date, ``Thu May 14 09:30:15.005 2026``: milliseconds in three digits.

    python-can's writer leaves them unpadded (``15.5`` for 5 ms), which its own reader takes
    for 500 ms and which changes the line's width with the time.
    """
    return (f"{when.strftime('%a %b %d %H:%M:%S')}.{when.microsecond // 1000:03d} "
            f"{when.strftime('%Y')}")


def _redate_asc_header(writer: ASCWriter, when: str) -> None:
    """Date the file's ``date`` line as its trigger block.

    In the ASC format the ``date`` line is when the measurement started, and with
    ``timestamps absolute`` every time stamp counts from it; the trigger block of a recording
    that starts with the measurement has the same date. python-can's writer dates it with the
    wall clock when the file is opened, which is neither the run's start given to the log nor
    the first frame's time: can-utils' ``asc2log`` takes that line as time zero, so it placed a
    log whose run started earlier (a replayed or test start time) at the moment the file was
    written. Only python-can's header is in the file yet: it is read back and written again
    with the new first line.
    """
    file = writer.file
    file.flush()
    with open(file.name, encoding=file.encoding) as written:
        header = written.read()
    first, _, rest = header.partition("\n")
    if not first.startswith("date "):
        raise ValueError(f"{file.name}: python-can's ASC header does not start with a date "
                         f"line: {first!r}")
    file.seek(0)
    file.truncate()
    file.write(f"date {when}\n{rest}")


def _begin_asc_trigger_block(writer: ASCWriter, first_s: float, start_epoch_s: float) -> None:
    """What ``ASCWriter.log_event`` writes before its first frame, dated by the run's start.

    The trigger block and the header's ``date`` line are dated ``start_epoch_s + first_s``
    (local time, as python-can writes the ``date`` line) and the time stamps are counted from
    the first frame's ``first_s``.
    """
    when = _asc_date(dt.datetime.fromtimestamp(start_epoch_s + first_s))
    _redate_asc_header(writer, when)
    writer.file.write(f"Begin Triggerblock {when}\n")
    writer.header_written = True
    writer.started = writer.last_timestamp = first_s
    writer.log_event("Start of measurement")


class BusLog:
    """The run's bus log in one or more formats.

    Parameters
    ----------
    directory
        Where the files go (``<stem>.<format>`` each).
    stem, formats, channel
        File stem, the formats (file suffixes python-can knows), the channel name written.
    start_epoch_s
        POSIX time of the run's time 0 (default: when the log is opened, which is when the
        recorder starts the run); dates the ``.asc`` trigger block.
    """

    def __init__(self, directory: Path, *, stem: str = "bus",
                 formats: Iterable[str] = DEFAULT_FORMATS, channel: str = "can0",
                 start_epoch_s: float | None = None) -> None:
        self.start_epoch_s = time.time() if start_epoch_s is None else start_epoch_s
        self.paths = [directory / f"{stem}.{fmt.lstrip('.')}" for fmt in formats]
        self.channel = channel
        self._writers: list[can.Listener] = []
        try:
            for path in self.paths:
                self._writers.append(_open_writer(path))
        except BaseException:
            self.close()
            raise
        self._fast = [_fast_text(w, channel) for w in self._writers]
        #: lines formatted here and not yet handed to each writer's file
        self._pending: list[list[str]] = [[] for _ in self._writers]
        self._batched = 0
        #: (time threshold, [(formatter, time origin, pending lines)]) once every writer is
        #: fast and has written its first frame: the path of nearly every frame
        self._steady: tuple[float, list[tuple[_Formatter, float, list[str]]]] | None = None
        self.frames = 0

    def write(self, msg: can.Message, time_s: float, *, rx: bool) -> None:
        """Log ``msg`` at ``time_s`` (the run clock's time); ``rx``: received by the rig."""
        steady = self._steady
        if steady is not None and time_s >= steady[0] \
                and not (msg.is_error_frame or msg.is_remote_frame or msg.is_fd):
            for formatter, origin, lines in steady[1]:
                lines.append(formatter(msg, time_s - origin, rx))
            self._batched += 1
            if self._batched >= _BATCH:
                self._flush()
        else:
            self._write_any(msg, time_s, rx)
        self.frames += 1

    def _write_any(self, msg: can.Message, time_s: float, rx: bool) -> None:
        """Any frame, any writer: formatted here where that gives the writer's own line.

        Else the frame goes through the writer (after the lines formatted here, to keep the order).
        """
        ordinary = not (msg.is_error_frame or msg.is_remote_frame or msg.is_fd)
        stamped = None
        for writer, fast, lines in zip(self._writers, self._fast, self._pending, strict=True):
            if type(writer) is ASCWriter and not writer.header_written:
                _begin_asc_trigger_block(writer, time_s, self.start_epoch_s)
            if fast is not None and ordinary:
                span = fast.span
                if span is None:
                    span = fast.span = fast.span_of(writer)
                if span is not None and time_s >= span[0]:
                    lines.append(fast.formatter(msg, time_s - span[1], rx))
                    continue
            if lines:
                fast.write("".join(lines))            # type: ignore[union-attr]
                lines.clear()
            if stamped is None:
                stamped = _stamped(msg, time_s, rx=rx, channel=self.channel)
            writer.on_message_received(stamped)
        if self._writers and all(f is not None and f.span is not None for f in self._fast):
            spans = [f.span for f in self._fast if f is not None and f.span is not None]
            self._steady = (max(s[0] for s in spans), [
                (f.formatter, s[1], lines) for f, s, lines in
                zip(self._fast, spans, self._pending, strict=True) if f is not None])

    def _flush(self) -> None:
        self._batched = 0
        for fast, lines in zip(self._fast, self._pending, strict=True):
            if lines:
                fast.write("".join(lines))            # type: ignore[union-attr]
                lines.clear()

    def close(self) -> None:
        """Write what is pending and close every file.

        Each writer is closed even if another one fails; the first failure is raised after.
        """
        writers, self._writers = self._writers, []
        self._steady = None
        problems: list[BaseException] = []
        try:
            self._flush()
        except Exception as exc:
            problems.append(exc)
        for writer in writers:
            try:
                writer.stop()
            except Exception as exc:
                problems.append(exc)
        if problems:
            raise problems[0]


#: where the DUT's frames nobody heard go, beside the bus logs
UNHEARD_NAME = "bus-unheard.log"


class UnheardLog:
    """The DUT's frames a fault kept from the rig, in candump lines.

    Each as ``T`` (sent, by the DUT), in run time, through python-can's own writer (they are
    few: a cut wire's seconds).

    Parameters
    ----------
    directory
        The run's directory (the file is ``bus-unheard.log`` there).
    channel
        The channel name written (the bus log's).
    """

    def __init__(self, directory: Path, *, channel: str = "can0") -> None:
        self.path = directory / UNHEARD_NAME
        self.channel = channel
        self._writer = CanutilsLogWriter(self.path)
        self.frames = 0
        self.first_s: float | None = None
        self.last_s: float | None = None
        self.ids: dict[str, int] = {}

    def write(self, msg: can.Message, time_s: float) -> None:
        """Log ``msg``, a DUT frame nobody received, at run time ``time_s``."""
        self._writer.on_message_received(_stamped(msg, time_s, rx=False, channel=self.channel))
        self.frames += 1
        if self.first_s is None:
            self.first_s = time_s
        self.last_s = time_s
        label = (f"0x{msg.arbitration_id:08X}" if msg.is_extended_id
                 else f"0x{msg.arbitration_id:03X}")
        self.ids[label] = self.ids.get(label, 0) + 1

    def summary(self) -> dict[str, Any]:
        """What the record says of them: how many, when, which identifiers, the file."""
        def stamp(t: float | None) -> float | None:
            return None if t is None else round(t, 6)       # the log's resolution
        return {"frames": self.frames, "first_s": stamp(self.first_s),
                "last_s": stamp(self.last_s),
                "ids": dict(sorted(self.ids.items())), "file": self.path.name}

    def close(self) -> None:
        """Write what is pending and close the file."""
        self._writer.stop()
