"""GNSS NMEA output on a pseudo-terminal, read back through pyserial as a DUT would."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import serial

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.gnss_serial import GnssSerialPort, PtySerialPort, SerialPortError
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
