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

and at the end ``as-applied.geojson`` (the as-applied map of the first implement that connected)
and ``summary.json``. With the Virtual Terminal (:class:`ServeVt`, ``--vt``), ``vt/``: the
implement's screens as they are drawn (live in the staging directory like the logs) and, at
the end, ``vt/vt.json`` (:func:`hil.isobus.vt.screens.vt_record`); they move into ``out`` with
the rest, however the serve ends. A disk that refuses a write ends the serve: what was
recorded until then is moved into ``out`` all the same, and the error names the file.

``summary.json`` is final however the serve ends: ``"status"`` is ``finished`` (the duration
ran out), ``interrupted`` (Ctrl-C, SIGTERM or SIGHUP; ``"signal"`` names it) or ``error`` (a bus
error, a disk that refused a write, a bug: ``"error"`` says what), and the staging directory is
gone; only SIGKILL, which no process can answer, leaves the placeholder (``"running"``, naming
the staging directory, which the next serve into ``out`` removes).

What the TC records goes to ``tc.jsonl`` as it happens (at most a slice's worth in memory), not
into memory for the whole serve: a serve of hours with a client sending thousands of values a
second stays the size it started. Unsolicited traffic is answered and logged at a bounded rate
(one line per address and second, then a count). The summary counts the TC's events by kind,
the transfers by how they ended, and the frames dropped on arrival, and says where the TC is:
``tc_address`` (``null`` when it holds none) and ``tc_address_changes``.

No client's input ends the serve: a pool the tractor cannot use is refused at activation with
the standard's codes, and a client whose messages raise loses its session (``client error``),
the TECU and every other client going on.
"""

from __future__ import annotations

import contextlib
import json
import math
import shutil
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, TextIO

import can

from hil.bus.registry import open_bus
from hil.errors import BusError
from hil.isobus import ddi as dd
from hil.isobus.tc.records import Event, EventKind, LoggedValue, ReceivedAcknowledge, Record
from hil.isobus.tractor import Tractor
from hil.isobus.wire import drive
from hil.record.atomic import named_os_error, write_json_atomic
from hil.record.staging import Staging, is_storage_error
from hil.rig.device import Device

if TYPE_CHECKING:   # the VT (and its browser page's aiohttp) is imported by a serve with it
    from hil.isobus.vt.attach import AttachedVt
    from hil.isobus.vt.server import VtOptions

__all__ = ["LoggedDevice", "ServeResult", "ServeVt", "serve"]

#: how long each slice of the real-time loop runs before the logs are flushed
SLICE_S = 0.2
#: what a serve writes besides ``summary.json``, moved into ``out`` at its end (``vt``: the
#: VT's folder, with the VT only)
OUTPUTS = ("bus.log", "tc.jsonl", "as-applied.geojson", "vt")
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
class ServeVt:
    """The Virtual Terminal of a serve (``hil isobus serve --vt``, ``--vt-browser PORT``).

    Attributes
    ----------
    browser_port : int, optional
        Serve the browser VT on this port of ``browser_host`` (0: a free one, printed).
    browser_host : str
        Where the browser VT listens.
    options : VtOptions, optional
        The VT (default: version 4, 480 px).
    """

    browser_port: int | None = None
    browser_host: str = "127.0.0.1"
    options: VtOptions | None = None


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


#: how many of the TC's address changes the summary lists (all are counted)
ADDRESS_CHANGES_KEPT = 50


class _TcLog:
    """What the TC records, as ``tc.jsonl`` lines: taken as it happens (the TC's recorder),
    written at each :meth:`flush` (so a write the disk refuses is the file's, not the bus's),
    events also to the console. Holds at most one slice's lines."""

    def __init__(self, file: IO[str], console: Callable[[str], None] | None) -> None:
        self.file = file
        self.console = console
        self._lines: list[str] = []
        #: the TC's own address changes (lost, claimed), the first ADDRESS_CHANGES_KEPT
        self.address_changes: list[dict[str, Any]] = []

    def record(self, item: Record) -> None:
        if isinstance(item, Event):
            line = _event_line(item)
            if item.kind in (EventKind.ADDRESS_LOST, EventKind.ADDRESS_CLAIMED) and len(
                    self.address_changes) < ADDRESS_CHANGES_KEPT:
                self.address_changes.append(line)
            if self.console is not None:
                who = f"0x{item.address:02X}" if item.address is not None else "TC"
                self.console(f"{item.time_s:8.2f} s  {who}  {item.kind.value}"
                             + (f": {item.detail}" if item.detail else ""))
        elif isinstance(item, LoggedValue):
            line = _value_line(item)
        else:
            line = _ack_line(item)
        self._lines.append(json.dumps(line))

    def flush(self) -> None:
        lines, self._lines = self._lines, []
        if lines:
            self.file.write("\n".join(lines) + "\n")
        self.file.flush()


@contextmanager
def _opened(path: Path, mode: str = "w") -> Iterator[TextIO]:
    try:
        handle = path.open(mode, encoding="utf-8")
    except OSError as exc:
        raise BusError(f"cannot write {path}: {exc.strerror or exc}") from exc
    with handle:
        yield handle


class Hangup(KeyboardInterrupt):
    """SIGHUP (the terminal closed): ends a serve as Ctrl-C does, its record written."""


@contextmanager
def _hangup_ends_the_serve() -> Iterator[None]:
    """SIGHUP raises :class:`Hangup` inside (main thread only; ``hil``'s own handlers turn
    SIGINT and SIGTERM into ``KeyboardInterrupt`` already)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def hangup(signum: int, frame: object) -> None:
        raise Hangup(f"signal {signum}")

    previous = signal.signal(signal.SIGHUP, hangup)
    try:
        yield
    finally:
        signal.signal(signal.SIGHUP, previous)


def _signal_name(exc: KeyboardInterrupt) -> str:
    if isinstance(exc, Hangup):
        return "SIGHUP"
    if type(exc).__name__ == "Terminated":       # hil.cli.main's SIGTERM
        return "SIGTERM"
    return "SIGINT"


def serve(tractor: Tractor, bus_spec: str, out: Path, *, duration_s: float = math.inf,
          console: Callable[[str], None] | None = print,
          clock: Callable[[], float] = time.monotonic,
          vt: ServeVt | None = None) -> ServeResult:
    """Run ``tractor`` on ``bus_spec`` in real time until ``duration_s`` or Ctrl-C.

    The TC's records go to ``tc.jsonl`` and are not kept in memory (the tractor's TC is set
    so); received pools are checked in a thread of their own, so the TECU's messages stay on
    time meanwhile. With ``vt``, the Virtual Terminal joins the tractor's network beside the
    TC, its screens and record written into ``vt/`` of the staging directory (see the module
    docstring); its browser page, if asked for, is started before anything is written, so a
    port that cannot be listened on leaves ``out`` as it was.

    Returns
    -------
    ServeResult
        Run time reached, frames logged, counts, whether a DDOP was activated, whether it
        was interrupted.

    Raises
    ------
    hil.errors.BusError
        The bus cannot be opened or fails, or ``out`` cannot be written (what was recorded
        until then is on disk, and ``summary.json`` says why it ended).
    """
    attached = None
    if vt is not None:
        from hil.isobus.vt.attach import attach_vt

        attached = attach_vt(tractor.network, options=vt.options, screens_dir=None,
                             browser_port=vt.browser_port, browser_host=vt.browser_host,
                             console=console if console is not None else print)
    try:
        with _hangup_ends_the_serve():
            return _serve(tractor, bus_spec, out, duration_s=duration_s, console=console,
                          clock=clock, attached=attached)
    finally:
        if attached is not None and attached.browser is not None:
            attached.browser.stop()


def _serve(tractor: Tractor, bus_spec: str, out: Path, *, duration_s: float,
           console: Callable[[str], None] | None, clock: Callable[[], float],
           attached: AttachedVt | None = None) -> ServeResult:
    tc = tractor.tc
    tc.keep_records = False
    checker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="tc-ddop-check")
    tc.checker = checker
    ending: dict[str, Any] = {"status": "finished"}
    interrupted = False
    now = 0.0
    logged: LoggedDevice | None = None
    tc_log: _TcLog | None = None
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
    refused = _Refused(staging.path)
    if attached is not None:        # the screens drawn live into the staging directory
        attached.screens_dir = attached.recorder.directory = staging.path / "vt"
    try:
        # from here on, whatever ends the serve (a signal as soon as the line is out) writes
        # its summary
        if console is not None:
            console(f"live files (tail -f them): {staging.path}/tc.jsonl, bus.log; moved into "
                    f"{out}/ at the end")
        with refused.noting("bus.log"):
            writer = can.Logger(str(staging.path / "bus.log"))
        if refused.error is None:
            logged = LoggedDevice(tractor.network, writer, epoch_s=time.time())
            try:
                with refused.noting("tc.jsonl"), \
                        _opened(staging.path / "tc.jsonl") as tc_file:
                    tc_log = _TcLog(tc_file, console)
                    tc.recorder = tc_log.record
                    try:
                        while now < duration_s and refused.error is None:
                            with refused.noting("bus.log"):
                                now = drive(logged, bus, min(SLICE_S, duration_s - now),
                                            clock=clock, start_s=now)
                            with refused.noting("tc.jsonl"):
                                tc_log.flush()
                    except KeyboardInterrupt as exc:
                        interrupted = True
                        ending = {"status": "interrupted", "signal": _signal_name(exc)}
                    except can.CanError as exc:
                        raise BusError(f"{bus_spec}: {exc}") from exc
                    finally:
                        tc.recorder = None
                        with refused.noting("tc.jsonl"):
                            tc_log.flush()
            finally:
                with refused.noting("bus.log"):
                    writer.stop()
    except BaseException as exc:
        # a bus error, a bug, a second signal: what was recorded moves into out all the same,
        # with a summary that says how the serve ended
        bus.shutdown()
        checker.shutdown(wait=True, cancel_futures=True)
        if isinstance(exc, KeyboardInterrupt):
            ending = {"status": "interrupted", "signal": _signal_name(exc)}
        else:
            ending = {"status": "error", "error": f"{type(exc).__name__}: {exc}"
                      if not isinstance(exc, BusError | OSError) else str(exc)}
        with contextlib.suppress(Exception):
            _write_summary(staging, tractor, logged, now, interrupted, ending, tc_log)
        with contextlib.suppress(Exception):
            _close_vt(attached)
        _promote(staging)
        raise
    bus.shutdown()
    checker.shutdown(wait=True, cancel_futures=True)
    result = ServeResult(run_time_s=now, frames=logged.frames if logged else 0,
                         events=tc.counts["events"], values=tc.counts["values"],
                         activated=tc.event_counts[EventKind.ACTIVATED] > 0,
                         interrupted=interrupted)
    if refused.error is None:
        with refused.noting("as-applied.geojson"):
            record = tractor.as_applied()
            if record is not None and len(record):
                record.save_geojson(staging.path / "as-applied.geojson")
    if refused.error is None and attached is not None:
        with refused.noting("vt/vt.json"):
            _close_vt(attached)
    if refused.error is not None:
        ending = {"status": "error", "error": str(refused.in_out(out))}
    # a small file: it may still fit where the log did not; if not, out's placeholder stays
    with refused.noting("summary.json"):
        _write_summary(staging, tractor, logged, now, interrupted, ending, tc_log)
    # however the serve ended, what it recorded moves into out (renames: no space needed)
    _promote(staging)
    if refused.error is not None:
        raise refused.in_out(out)
    return result


def _write_summary(staging: Staging, tractor: Tractor, logged: LoggedDevice | None,
                   now: float, interrupted: bool, ending: dict[str, Any],
                   tc_log: _TcLog | None) -> None:
    """``summary.json``: how the serve ended, its counts, where the TC is."""
    tc = tractor.tc
    address = tractor.tc_function.address
    summary: dict[str, Any] = {
        **ending,
        "run_time_s": now, "frames": logged.frames if logged else 0,
        "events": tc.counts["events"], "values": tc.counts["values"],
        "acknowledgements": tc.counts["acknowledgements"],
        "activated": tc.event_counts[EventKind.ACTIVATED] > 0,
        "interrupted": interrupted,
        "event_counts": {k.value: n for k, n in sorted(tc.event_counts.items(),
                                                        key=lambda kv: kv[0].value)},
        "transfers": dict(sorted(tractor.network.transport.counts.items())),
        "dropped_frames": dict(sorted(tractor.network.dropped.items())),
        "tc_address": address,
        "tc_address_changes": tc_log.address_changes if tc_log is not None else [],
        "tecu_address": tractor.tecu.port.address,
    }
    write_json_atomic(staging.path / "summary.json", summary)


def _trim_to_last_line(path: Path) -> None:
    """Cut a line file the disk refused back to its last whole line, so that candump readers
    and JSON-lines readers take it (shrinking a file needs no space)."""
    with contextlib.suppress(OSError), path.open("rb+") as handle:
        data = handle.read()
        handle.truncate(data.rfind(b"\n") + 1)


def _close_vt(attached: AttachedVt | None) -> None:
    """The VT's record, ``vt/vt.json``, beside its screens (when the VT took its address)."""
    if attached is not None:
        attached.close()


def _promote(staging: Staging) -> None:
    """Move a serve's files into ``out``: they replace the previous serve's as a set (an
    as-applied map or VT folder of an earlier run must not sit beside this run's log)."""
    for name in OUTPUTS:
        if not (staging.path / name).exists():
            old = staging.out / name
            if old.is_dir() and not old.is_symlink():
                shutil.rmtree(old, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    old.unlink()
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
