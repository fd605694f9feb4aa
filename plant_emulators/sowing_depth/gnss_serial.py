"""The GNSS speed module's serial line: NMEA sentences written to a pseudo-terminal.

:class:`PtySerialPort` opens a pty pair in raw mode; the DUT opens :attr:`PtySerialPort.path`
(``/dev/pts/N``) by name, with pyserial or ``open(2)``, as it would a USB-serial adapter.
:class:`GnssSerialPort` writes one epoch (RMC, VTG, GGA) each time the caller's simulated time
passes the next epoch at ``gnss.output_rate_hz``. It owns no thread and no clock: the rig calls
:meth:`GnssSerialPort.emit` with its time.

Writes never block. A pty buffers about 4 KiB when nobody reads; when it is full the epoch is
dropped and counted (:attr:`GnssSerialPort.dropped_epochs`), as a UART overruns. A DUT that opens
the port late first reads what was buffered: call :meth:`PtySerialPort.discard_unread` before
the DUT starts if that matters.

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
import termios
import tty
from types import TracebackType
from typing import Protocol

from hil.errors import HilError
from plant_emulators.sowing_depth.nmea import GnssReceiver

__all__ = ["GnssSerialPort", "Kinematics", "PtySerialPort", "SerialPortError"]


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
        """Write ``data`` whole, or nothing if the buffer is full; return whether it was written."""
        if self._closed:
            raise SerialPortError(f"{self.path} is closed")
        try:
            written = os.write(self._master, data)
        except BlockingIOError:
            return False
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EIO):
                return False
            raise SerialPortError(f"{self.path}: write failed: {exc}") from exc
        return written == len(data)

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
    """

    def __init__(self, receiver: GnssReceiver, source: Kinematics,
                 port: PtySerialPort | None = None) -> None:
        self.receiver = receiver
        self.source = source
        self.port = PtySerialPort() if port is None else port
        self._period_s = 1.0 / receiver.config.output_rate_hz
        self._next_epoch = 0
        self.sent_epochs = 0
        self.dropped_epochs = 0
        self.skipped_epochs = 0

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
        if self.port.write("".join(sentences).encode("ascii")):
            self.sent_epochs += 1
            return len(sentences)
        self.dropped_epochs += 1
        return 0

    def close(self) -> None:
        """Close the pseudo-terminal."""
        self.port.close()

    def __enter__(self) -> GnssSerialPort:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
