"""GNSS NMEA output on a pseudo-terminal, read back through pyserial as a DUT would."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import serial

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.gnss_serial import (
    LINE_QUEUE_BYTES,
    GnssSerialPort,
    PtySerialPort,
    SerialPortError,
)
from plant_emulators.sowing_depth.nmea import GnssReceiver, parse_rmc, parse_sentence, parse_vtg


class Cart:
    """Stands in for the plant."""

    def __init__(self) -> None:
        self.distance_m = 0.0
        self.ground_speed_mps = 1.25


@pytest.fixture
def gnss() -> Iterator[GnssSerialPort]:
    port = GnssSerialPort(GnssReceiver(load_rig_config().gnss, np.random.default_rng(0)), Cart())
    yield port
    port.close()


def test_a_dut_reads_checked_sentences_at_10_hz(gnss: GnssSerialPort) -> None:
    cart = gnss.source
    assert gnss.path.startswith("/dev/")
    with serial.Serial(gnss.path, baudrate=115200, timeout=1.0) as dut:
        written = 0
        for k in range(1001):                      # 1 s of 1 ms steps
            t = k * 0.001
            cart.distance_m = 1.25 * t             # type: ignore[attr-defined]
            written += gnss.emit(t)
        assert written == 33 and gnss.sent_epochs == 11
        lines = [dut.readline() for _ in range(33)]
    kinds = [parse_sentence(line).kind for line in lines]
    assert kinds == ["RMC", "VTG", "GGA"] * 11
    times = [parse_rmc(line).time_utc for line in lines[::3]]
    assert times == [f"0130{s // 10:02d}.{s % 10}0" for s in range(11)]
    speed = parse_vtg(lines[-2]).speed_kmh
    assert speed == pytest.approx(4.5, abs=0.5)


def test_late_calls_skip_epochs_instead_of_bursting(gnss: GnssSerialPort) -> None:
    with serial.Serial(gnss.path, timeout=1.0) as dut:
        assert gnss.emit(0.0) == 3
        assert gnss.emit(0.05) == 0
        assert gnss.emit(0.55) == 3               # epochs 0.1-0.4 missed, 0.5 written
        assert gnss.skipped_epochs == 4
        lines = [dut.readline() for _ in range(6)]
    assert parse_rmc(lines[3]).time_utc == "013000.50"


def test_unread_output_is_dropped_not_blocking(gnss: GnssSerialPort) -> None:
    for k in range(3000):
        gnss.emit(k * 0.1)
    assert gnss.dropped_epochs > 0 and gnss.sent_epochs > 0
    gnss.port.discard_unread()
    with serial.Serial(gnss.path, timeout=1.0) as dut:
        gnss.emit(400.0)
        assert parse_rmc(dut.readline()).time_utc == "013640.00"


def test_closed_port_refuses_writes() -> None:
    port = PtySerialPort()
    port.close()
    port.close()
    with pytest.raises(SerialPortError, match="closed"):
        port.write(b"$")


def test_every_epoch_is_counted_written_overrun_dropped_or_late() -> None:
    notes: list[tuple[float, str, str]] = []
    gnss = GnssSerialPort(GnssReceiver(load_rig_config().gnss, np.random.default_rng(0)),
                          Cart(), note=lambda t, kind, detail: notes.append((t, kind, detail)))
    try:
        for k in range(3000):                       # nobody reads: the buffer fills
            gnss.emit(k * 0.1)
        gnss.emit(300.15)                           # one epoch late (300.0 skipped)
        counts = gnss.counts()
    finally:
        gnss.close()
    assert counts["written"] > 0 and counts["dropped"] > 0
    assert counts["late"] == 1
    assert counts["written"] + counts["overrun"] + counts["dropped"] + counts["late"] == 3002
    assert 0 < counts["unread_bytes"] <= 4096 * 4
    # nobody read the port: what got through after the first loss is at most what the kernel
    # moved from the pty's buffer into the line discipline's queue when it got to it (late on
    # a loaded host: 20 epochs of 187 bytes seen)
    assert counts["bytes_after_loss"] <= LINE_QUEUE_BYTES
    assert 0 < counts["first_loss_s"] < 300
    kinds = [kind for _, kind, _ in notes]
    assert kinds.count("gnss-dropped") == 1 and kinds.count("gnss-overrun") <= 1
    assert all("too slowly" in detail for _, _, detail in notes)


def test_a_partly_written_epoch_is_an_overrun(gnss: GnssSerialPort) -> None:
    class HalfFull(PtySerialPort):
        def write_some(self, data: bytes) -> int:
            return len(data) // 2

    gnss.port.close()
    gnss.port = HalfFull()
    gnss.emit(0.0)
    assert (gnss.sent_epochs, gnss.overrun_epochs, gnss.dropped_epochs) == (0, 1, 0)


def test_a_reading_dut_loses_nothing(gnss: GnssSerialPort) -> None:
    with serial.Serial(gnss.path, timeout=1.0) as dut:
        for k in range(50):
            gnss.emit(k * 0.1)
            for _ in range(3):
                dut.readline()
        counts = gnss.counts()
    assert counts == {"written": 50, "overrun": 0, "dropped": 0, "late": 0,
                      "unread_bytes": 0, "first_loss_s": None, "written_after_loss": 0,
                      "bytes_after_loss": 0, "line_queue_bytes": LINE_QUEUE_BYTES}


def test_a_slow_reader_gets_epochs_through_after_the_first_loss(gnss: GnssSerialPort) -> None:
    with serial.Serial(gnss.path, timeout=0.5) as dut:
        for k in range(400):
            gnss.emit(k * 0.1)
            if k % 40 == 39:                         # reads a little, rarely
                dut.read(4096)
        counts = gnss.counts()
    assert counts["dropped"] + counts["overrun"] > 0
    assert counts["written_after_loss"] > 0
    assert counts["bytes_after_loss"] > LINE_QUEUE_BYTES      # it read: more than the queue
