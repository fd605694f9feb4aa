"""The GNSS speed module's serial line: NMEA sentences written to a pseudo-terminal.

:class:`PtySerialPort` opens a pty pair in raw mode; the DUT opens :attr:`PtySerialPort.path`
(``/dev/pts/N``) by name, with pyserial or ``open(2)``, as it would a USB-serial adapter.
:class:`GnssSerialPort` writes one epoch (RMC, VTG, GGA) each time the caller's simulated time
passes the next epoch at ``gnss.output_rate_hz``. It owns no thread and no clock: the rig calls
:meth:`GnssSerialPort.emit` with its time.

Writes never block. A pty buffers about 4 KiB when nobody reads; a DUT that reads too slowly
loses epochs as it would behind a real receiver's UART, and every epoch is counted
(:meth:`GnssSerialPort.counts`, which the rig puts in the run record):

* *written*: the whole epoch went onto the line;
* *overrun*: the buffer filled in the middle of the epoch: part of it is on the line, so the
  DUT reads a truncated sentence (which the next epoch's first sentence runs into, as after
  a UART overrun) and must reject it by its checksum;
* *dropped*: the buffer was full: nothing of the epoch reached the line;
* *late*: the rig's own loop called too late and the epoch was never produced (the bench's
  fault, not the DUT's);
* *unread_bytes*: what is still buffered in the slave's input queue, unread by the DUT, when
  the run ends;
* *first_loss_s* and *written_after_loss*: when the first epoch was overrun or dropped, and
  how many were written whole after it. None written after it means the line was never
  drained again: the DUT stopped reading (or never read: a DUT that does not use the GNSS);
  some written after it means the DUT reads, too slowly;
* *bytes_after_loss*: the bytes the line took after the first loss (whole epochs and the part
  of an overrun one). A line nobody reads still takes up to :data:`LINE_QUEUE_BYTES` after it:
  the kernel moves what the pty's own buffer holds into the line discipline's queue when it
  gets to it (late on a loaded host), which makes room without any reader. More than that
  after the loss means the DUT read. The counts carry that bound as *line_queue_bytes*.

A DUT that opens the port late first reads what was buffered: call
:meth:`PtySerialPort.discard_unread` before the DUT starts if that matters.

Example
-------
>>> import serial
>>> from plant_emulators.sowing_depth.config import load_rig_config
>>> import numpy as np
>>> from plant_emulators.sowing_depth.nmea import GnssReceiver
>>> class Cart:
...     distance_m, ground_speed_mps = 0.0, 1.0
>>> with GnssSerialPort(GnssReceiver(load_rig_config().gnss, np.random.default_rng(0)),
...                     Cart()) as gnss, serial.Serial(gnss.path, timeout=1.0) as dut:
...     gnss.emit(0.0)
...     dut.readline().startswith(b"$GNRMC")
3
True
"""

from __future__ import annotations

import errno
import fcntl
import os
import select
import termios
import tty
from collections.abc import Callable
from types import TracebackType
from typing import Protocol

from hil.errors import HilError
from plant_emulators.sowing_depth.nmea import GnssReceiver

__all__ = ["LINE_QUEUE_BYTES", "GnssSerialPort", "Kinematics", "PtySerialPort", "SerialPortError"]

#: what a pty's line discipline queues for the reader (Linux N_TTY_BUF_SIZE): at most this
#: much reaches a port nobody reads after the writer first found it full
LINE_QUEUE_BYTES = 4096

#: a run-record note: (time s, kind, detail)
Note = Callable[[float, str, str], None]


class SerialPortError(HilError, OSError):
    """The pseudo-terminal could not be opened or was used after close."""


class Kinematics(Protocol):
    """What the GNSS needs from the plant."""

    @property
    def distance_m(self) -> float: ...  # pragma: no cover

    @property
    def ground_speed_mps(self) -> float: ...  # pragma: no cover


class PtySerialPort:
    """A raw-mode pseudo-terminal; the slave side is the "serial port" a DUT opens by path."""

    def __init__(self) -> None:
        try:
            self._master, self._slave = os.openpty()
        except OSError as exc:
            raise SerialPortError(f"cannot open a pseudo-terminal: {exc}") from exc
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[4] = attrs[5] = termios.B115200
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        flags = fcntl.fcntl(self._master, fcntl.F_GETFL)
        fcntl.fcntl(self._master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self.path = os.ttyname(self._slave)
        self._closed = False

    def write(self, data: bytes) -> bool:
        """Write as much of ``data`` as the buffer takes; return whether all of it was."""
        return self.write_some(data) == len(data)

    def write_some(self, data: bytes) -> int:
        """Write as much of ``data`` as the buffer takes, never blocking; return how many
        bytes that was (0 when the buffer is full)."""
        if self._closed:
            raise SerialPortError(f"{self.path} is closed")
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EIO):
                return 0
            raise SerialPortError(f"{self.path}: write failed: {exc}") from exc

    def unread_bytes(self) -> int:
        """Bytes written but not yet read by the DUT (0 once closed)."""
        if self._closed:
            return 0
        buf = fcntl.ioctl(self._slave, termios.FIONREAD, b"\0\0\0\0")
        return int.from_bytes(buf, "little")

    def settled_unread_bytes(self) -> int:
        """:meth:`unread_bytes` once the kernel has moved all that was written into the
        reader's queue.

        Right after a write the bytes may still wait in the pty's own buffer, where FIONREAD
        does not count them (seen in 460 of 2,000 tries); a poll of the slave side waits
        for the move (as a read does), so this counts them.
        """
        if self._closed:
            return 0
        select.select([self._slave], [], [], 0)
        return self.unread_bytes()

    def discard_unread(self) -> None:
        """Throw away what was written but not yet read by the DUT."""
        if not self._closed:
            termios.tcflush(self._slave, termios.TCIFLUSH)

    def close(self) -> None:
        """Close both sides (idempotent)."""
        if not self._closed:
            self._closed = True
            os.close(self._master)
            os.close(self._slave)

    def __enter__(self) -> PtySerialPort:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class GnssSerialPort:
    """NMEA output of the GNSS speed module at ``output_rate_hz`` on a pseudo-terminal.

    Parameters
    ----------
    receiver : GnssReceiver
        Builds the sentences (and holds the ``fix_lost`` fault hook).
    source : Kinematics
        Where distance and ground speed come from (the plant).
    port : PtySerialPort, optional
        The line to write to (a new pty by default; closed by :meth:`close` either way).
    note : callable, optional
        ``note(time_s, kind, detail)`` on the first overrun and the first dropped epoch of
        the run (the rig's run-record notes), so the report says when the losses began.
    """

    def __init__(self, receiver: GnssReceiver, source: Kinematics,
                 port: PtySerialPort | None = None, note: Note | None = None) -> None:
        self.receiver = receiver
        self.source = source
        self.port = PtySerialPort() if port is None else port
        self._period_s = 1.0 / receiver.config.output_rate_hz
        self._next_epoch = 0
        self.note = note
        #: epochs written whole
        self.sent_epochs = 0
        #: epochs of which nothing was written (the buffer was full)
        self.dropped_epochs = 0
        #: epochs written in part (the buffer filled during the epoch)
        self.overrun_epochs = 0
        #: epochs never produced because the caller was late
        self.skipped_epochs = 0
        #: time of the first overrun or dropped epoch, and epochs written whole after it
        self.first_loss_s: float | None = None
        self.written_after_loss = 0
        #: bytes the line took after the first loss
        self.bytes_after_loss = 0

    @property
    def path(self) -> str:
        """Device path the DUT opens, e.g. ``/dev/pts/3``."""
        return self.port.path

    def emit(self, time_s: float) -> int:
        """Write the epoch due at ``time_s``, if any; return the number of sentences written.

        Epochs fall on multiples of the output period. If the caller is more than one period
        late, the missed epochs are skipped (counted in :attr:`skipped_epochs`) and only the
        latest is written, stamped with its own epoch time.
        """
        due = self._next_epoch * self._period_s
        if time_s + 1e-9 < due:
            return 0
        latest = int((time_s + 1e-9) / self._period_s)
        if latest > self._next_epoch:
            self.skipped_epochs += latest - self._next_epoch
        epoch_time = latest * self._period_s
        self._next_epoch = latest + 1
        src = self.source
        sentences = self.receiver.epoch(epoch_time, src.distance_m, src.ground_speed_mps)
        data = "".join(sentences).encode("ascii")
        written = self.port.write_some(data)
        if self.first_loss_s is not None:
            self.bytes_after_loss += written
        if written == len(data):
            self.sent_epochs += 1
            if self.first_loss_s is not None:
                self.written_after_loss += 1
            return len(sentences)
        if self.first_loss_s is None:
            self.first_loss_s = epoch_time
        if written:
            self.overrun_epochs += 1
            if self.overrun_epochs == 1 and self.note is not None:
                self.note(time_s, "gnss-overrun", f"GNSS serial buffer full during the epoch "
                          f"of {epoch_time:.1f} s: {written} of {len(data)} bytes written "
                          f"(the DUT reads its serial port too slowly)")
        else:
            self.dropped_epochs += 1
            if self.dropped_epochs == 1 and self.note is not None:
                self.note(time_s, "gnss-dropped", f"GNSS epoch of {epoch_time:.1f} s dropped: "
                          f"serial buffer full (the DUT reads its serial port too slowly)")
        return 0

    def counts(self) -> dict[str, int | float | None]:
        """Epochs written, overrun, dropped and late, the bytes left unread, when losses
        began and how many epochs got through after that (see the module docstring)."""
        return {"written": self.sent_epochs, "overrun": self.overrun_epochs,
                "dropped": self.dropped_epochs, "late": self.skipped_epochs,
                "unread_bytes": self.port.unread_bytes(),
                "first_loss_s": None if self.first_loss_s is None
                else round(self.first_loss_s, 3),
                "written_after_loss": self.written_after_loss,
                "bytes_after_loss": self.bytes_after_loss,
                # what a port nobody reads may still take after the loss: the report judges
                # bytes_after_loss against it, from the record, not a constant of its own
                "line_queue_bytes": LINE_QUEUE_BYTES}

    def close(self) -> None:
        """Close the pseudo-terminal."""
        self.port.close()

    def __enter__(self) -> GnssSerialPort:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
