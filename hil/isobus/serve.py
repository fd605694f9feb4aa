"""The tractor on its own, in real time on any bus: what ``hil isobus serve`` runs.

:func:`serve` opens a bus spec, puts a :class:`~hil.isobus.tractor.Tractor` (TECU and Task
Controller) on it and drives the field path in real time, so an implement's developers can work
against it interactively and an outside ISOBUS stack can be tested without a qualification.

It writes as every command that writes into ``--out`` does (:class:`hil.record.staging.Staging`):
into a staging directory inside ``out`` while it runs, moved into ``out`` when it ends, however
it ends (the end of ``--duration``, Ctrl-C, a bus error, a disk that refuses a write). So a
serve that cannot start leaves ``out`` as it found it, and while one runs ``out/summary.json``
says it has not finished (the previous summary kept as ``summary.previous.json``) and the
previous run's files stay in ``out`` until the new ones replace them. The staging files are
live, flushed every :data:`SLICE_S`: ``tail -f`` them at the path printed when the serve starts.

- ``bus.log``: every frame sent and received, candump format (python-can's writer; can-utils,
  cantools and SavvyCAN read it);
- ``tc.jsonl``: one JSON object per line for every connection event, value the implement sent
  and process data acknowledgement the TC received, in run time;

and at the end ``as-applied.geojson`` (the as-applied map of the implement, when one connected)
and ``summary.json``. A disk that refuses a write ends the serve: what was recorded until then
is moved into ``out`` all the same, and the error names the file.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, TextIO

import can

from hil.bus.registry import open_bus
from hil.errors import BusError
from hil.isobus import ddi as dd
from hil.isobus.tc.records import Event, LoggedValue, ReceivedAcknowledge
from hil.isobus.tractor import Tractor
from hil.isobus.wire import drive
from hil.record.atomic import named_os_error, write_json_atomic
from hil.record.staging import Staging, is_storage_error
from hil.rig.device import Device

__all__ = ["LoggedDevice", "ServeResult", "serve"]

#: how long each slice of the real-time loop runs before the logs are flushed
SLICE_S = 0.2
#: what a serve writes besides ``summary.json``, moved into ``out`` at its end
OUTPUTS = ("bus.log", "tc.jsonl", "as-applied.geojson")
#: the outputs written a line at a time, cut back to a whole line when the disk refuses one
LINE_FILES = ("bus.log", "tc.jsonl")


class LoggedDevice(Device):
    """A device whose frames, both ways, go to a python-can writer stamped with run time."""

    def __init__(self, inner: Device, writer: can.io.generic.MessageWriter,
                 epoch_s: float, channel: str = "can0") -> None:
        self.inner = inner
        self.name = inner.name
        self.writer = writer
        self.epoch_s = epoch_s
        self.channel = channel
        self.frames = 0

    def _log(self, msg: can.Message, time_s: float, rx: bool) -> None:
        self.writer.on_message_received(can.Message(
            timestamp=self.epoch_s + time_s, arbitration_id=msg.arbitration_id,
            is_extended_id=msg.is_extended_id, dlc=msg.dlc, data=msg.data,
            channel=self.channel, is_rx=rx))
        self.frames += 1

    def next_due(self, time_s: float) -> float:
        """As the wrapped device."""
        return self.inner.next_due(time_s)

    def emit(self, time_s: float) -> list[can.Message]:
        """The wrapped device's frames, logged as sent."""
        frames = self.inner.emit(time_s)
        for f in frames:
            self._log(f, time_s, rx=False)
        return frames

    def accepts(self, msg: can.Message) -> bool:
        """As the wrapped device."""
        return self.inner.accepts(msg)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        """Log the frame as received, hand it on, log the replies as sent."""
        self._log(msg, time_s, rx=True)
        replies = self.inner.on_frame(msg, time_s)
        for f in replies:
            self._log(f, time_s, rx=False)
        return replies


@dataclass(frozen=True)
class ServeResult:
    """How a serve ended."""

    run_time_s: float
    frames: int
    events: int
    values: int
    activated: bool
    interrupted: bool


def _event_line(e: Event) -> dict[str, Any]:
    return {"t": round(e.time_s, 4), "kind": "event", "event": e.kind.value,
            "address": e.address, "detail": e.detail}


def _value_line(v: LoggedValue) -> dict[str, Any]:
    try:
        name = dd.name_of(v.ddi)
    except (KeyError, ValueError):
        name = f"DDI {v.ddi}"
    return {"t": round(v.time_s, 4), "kind": "value", "address": v.address,
            "element": v.element, "ddi": v.ddi, "ddi_name": name, "value": v.value}


def _ack_line(a: ReceivedAcknowledge) -> dict[str, Any]:
    return {"t": round(a.time_s, 4), "kind": "acknowledge", "address": a.address,
            "element": a.element, "ddi": a.ddi, "errors": a.errors, "command": a.command}


class _TcLog:
    """Appends what the TC saw since the last call to ``tc.jsonl`` (and events to a console)."""

    def __init__(self, tractor: Tractor, file: IO[str],
                 console: Callable[[str], None] | None) -> None:
        self.tractor = tractor
        self.file = file
        self.console = console
        self.seen = [0, 0, 0]

    def flush(self) -> None:
        tc = self.tractor.tc
        lines: list[tuple[float, dict[str, Any]]] = []
        for i, (items, fmt) in enumerate(((tc.events, _event_line), (tc.values, _value_line),
                                          (tc.acknowledgements, _ack_line))):
            new = items[self.seen[i]:]
            self.seen[i] = len(items)
            lines.extend((item.time_s, fmt(item)) for item in new)  # type: ignore[operator]
            if i == 0 and self.console is not None:
                for e in new:
                    who = f"0x{e.address:02X}" if e.address is not None else "TC"
                    self.console(f"{e.time_s:8.2f} s  {who}  {e.kind.value}"
                                 + (f": {e.detail}" if e.detail else ""))
        for _, line in sorted(lines, key=lambda p: p[0]):
            self.file.write(json.dumps(line) + "\n")
        self.file.flush()


@contextmanager
def _opened(path: Path, mode: str = "w") -> Iterator[TextIO]:
    try:
        handle = path.open(mode, encoding="utf-8")
    except OSError as exc:
        raise BusError(f"cannot write {path}: {exc.strerror or exc}") from exc
    with handle:
        yield handle


def serve(tractor: Tractor, bus_spec: str, out: Path, *, duration_s: float = math.inf,
          console: Callable[[str], None] | None = print,
          clock: Callable[[], float] = time.monotonic) -> ServeResult:
    """Run ``tractor`` on ``bus_spec`` in real time until ``duration_s`` or Ctrl-C.

    Returns
    -------
    ServeResult
        Run time reached, frames logged, counts, whether a DDOP was activated, whether it
        was interrupted.

    Raises
    ------
    hil.errors.BusError
        The bus cannot be opened or fails, or ``out`` cannot be written (what was recorded
        until then is on disk).
    """
    bus = open_bus(bus_spec)
    try:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise named_os_error(exc, out) from exc
        staging = Staging(out, prefix=".serve-", outputs=OUTPUTS, record="summary.json")
        staging.begin({"status": "running",
                       "why": "hil isobus serve has not finished (or was killed); its live "
                              f"files are in {staging.path}"})
    except BaseException:
        bus.shutdown()
        raise
    if console is not None:
        console(f"live files (tail -f them): {staging.path}/tc.jsonl, bus.log; moved into "
                f"{out}/ at the end")
    refused = _Refused(staging.path)
    interrupted = False
    now = 0.0
    logged: LoggedDevice | None = None
    try:
        with refused.noting("bus.log"):
            writer = can.Logger(str(staging.path / "bus.log"))
        if refused.error is None:
            logged = LoggedDevice(tractor.network, writer, epoch_s=time.time())
            try:
                with refused.noting("tc.jsonl"), _opened(staging.path / "tc.jsonl") as tc_file:
                    tc_log = _TcLog(tractor, tc_file, console)
                    try:
                        while now < duration_s and refused.error is None:
                            with refused.noting("bus.log"):
                                now = drive(logged, bus, min(SLICE_S, duration_s - now),
                                            clock=clock, start_s=now)
                            with refused.noting("tc.jsonl"):
                                tc_log.flush()
                    except KeyboardInterrupt:
                        interrupted = True
                    except can.CanError as exc:
                        raise BusError(f"{bus_spec}: {exc}") from exc
                    finally:
                        with refused.noting("tc.jsonl"):
                            tc_log.flush()
            finally:
                with refused.noting("bus.log"):
                    writer.stop()
    except BaseException:
        # a bus error, or a second Ctrl-C: what was recorded moves into out all the same
        bus.shutdown()
        _promote(staging)
        raise
    bus.shutdown()
    result = ServeResult(run_time_s=now, frames=logged.frames if logged else 0,
                         events=len(tractor.tc.events), values=len(tractor.tc.values),
                         activated=any(e.kind.value == "activated" for e in tractor.tc.events),
                         interrupted=interrupted)
    if refused.error is None:
        with refused.noting("as-applied.geojson"):
            record = tractor.as_applied()
            if record is not None and len(record):
                record.save_geojson(staging.path / "as-applied.geojson")
    summary: dict[str, Any] = dict(result.__dict__)
    if refused.error is not None:
        summary["error"] = str(refused.in_out(out))
    # a small file: it may still fit where the log did not; if not, out's placeholder stays
    with refused.noting("summary.json"):
        write_json_atomic(staging.path / "summary.json", summary)
    # however the serve ended, what it recorded moves into out (renames: no space needed)
    _promote(staging)
    if refused.error is not None:
        raise refused.in_out(out)
    return result


def _trim_to_last_line(path: Path) -> None:
    """Cut a line file the disk refused back to its last whole line, so that candump readers
    and JSON-lines readers take it (shrinking a file needs no space)."""
    with contextlib.suppress(OSError), path.open("rb+") as handle:
        data = handle.read()
        handle.truncate(data.rfind(b"\n") + 1)


def _promote(staging: Staging) -> None:
    """Move a serve's files into ``out``: they replace the previous serve's as a set (an
    as-applied map of an earlier run must not sit beside this run's log)."""
    for name in OUTPUTS:
        if not (staging.path / name).exists():
            with contextlib.suppress(FileNotFoundError):
                (staging.out / name).unlink()
    staging.promote()


class _Refused:
    """The first write the disk refused during a serve, noted instead of raised: the serve
    stops, and what it recorded until then is kept."""

    def __init__(self, staging: Path) -> None:
        self.staging = staging
        self.error: OSError | None = None
        self.name = ""

    @contextmanager
    def noting(self, name: str) -> Iterator[None]:
        """Note a storage error raised inside while writing ``name`` (other errors go on)."""
        try:
            yield
        except OSError as exc:
            if not is_storage_error(exc):
                raise
            if self.error is None:
                self.error, self.name = exc, name
            if name in LINE_FILES:
                _trim_to_last_line(self.staging / name)

    def in_out(self, out: Path) -> OSError:
        """The noted error naming the file in ``out`` it was written to (moved there)."""
        assert self.error is not None
        return OSError(self.error.errno, self.error.strerror or str(self.error),
                       str(out / self.name))
