"""The tractor on its own, in real time on any bus: what ``hil isobus serve`` runs.

:func:`serve` opens a bus spec, puts a :class:`~hil.isobus.tractor.Tractor` (TECU and Task
Controller) on it and drives the field path in real time, so an implement's developers can work
against it interactively and an outside ISOBUS stack can be tested without a qualification. It
writes, into ``out``, as the run goes (nothing is lost on Ctrl-C or a bus error):

- ``bus.log``: every frame sent and received, candump format (python-can's writer; can-utils,
  cantools and SavvyCAN read it);
- ``tc.jsonl``: one JSON object per line for every connection event, value the implement sent
  and process data acknowledgement the TC received, in run time;

and at the end ``as-applied.geojson`` (the as-applied map of the implement, when one connected)
and ``summary.json``.
"""

from __future__ import annotations

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
from hil.rig.device import Device

__all__ = ["LoggedDevice", "ServeResult", "serve"]

#: how long each slice of the real-time loop runs before the logs are flushed
SLICE_S = 0.2


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
    out.mkdir(parents=True, exist_ok=True)
    bus = open_bus(bus_spec)
    interrupted = False
    now = 0.0
    try:
        writer = can.Logger(str(out / "bus.log"))
        with _opened(out / "tc.jsonl") as tc_file:
            logged = LoggedDevice(tractor.network, writer, epoch_s=time.time())
            tc_log = _TcLog(tractor, tc_file, console)
            try:
                while now < duration_s:
                    now = drive(logged, bus, min(SLICE_S, duration_s - now), clock=clock,
                                start_s=now)
                    tc_log.flush()
            except KeyboardInterrupt:
                interrupted = True
            except can.CanError as exc:
                raise BusError(f"{bus_spec}: {exc}") from exc
            finally:
                tc_log.flush()
                writer.stop()
    finally:
        bus.shutdown()
    record = tractor.as_applied()
    if record is not None and len(record):
        record.save_geojson(out / "as-applied.geojson")
    result = ServeResult(run_time_s=now, frames=logged.frames, events=len(tractor.tc.events),
                         values=len(tractor.tc.values),
                         activated=any(e.kind.value == "activated" for e in tractor.tc.events),
                         interrupted=interrupted)
    (out / "summary.json").write_text(json.dumps(result.__dict__, indent=2) + "\n",
                                      encoding="utf-8")
    return result
