"""Ground speed for the depth controller: ISO 11783 GBSD frames and the GNSS receiver's NMEA.

Section 2, "CAN adapter": speed comes from PGN 65097 and, when the rig names a serial port in
``AGRIHIL_GNSS_PORT``, from the BeiDou module's RMC/VTG sentences (parsed and checksum-checked
by the rig's own :mod:`plant_emulators.sowing_depth.nmea`). The speed is *known* when some
source gave a valid speed within ``timeout_s``; the most recent one wins. A source that says it
has no speed (RMC status V, VTG mode N, a J1939 "not available") stops counting at once.
"""

from __future__ import annotations

import serial

from plant_emulators.sowing_depth.nmea import NmeaError, parse_rmc, parse_sentence, parse_vtg


class SpeedSources:
    """Latest (speed or None, time) per source; :meth:`speed` is the known speed or None."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self.latest: dict[str, tuple[float | None, float]] = {}

    def update(self, source: str, speed_mps: float | None, now_s: float) -> None:
        self.latest[source] = (speed_mps, now_s)

    def speed(self, now_s: float) -> float | None:
        best: tuple[float, float] | None = None
        for value, at in self.latest.values():
            if value is None or now_s - at > self.timeout_s + 1e-9:
                continue
            if best is None or at > best[1]:
                best = (value, at)
        return None if best is None else best[0]


def nmea_speed(line: bytes) -> tuple[bool, float | None]:
    """(is a speed sentence, speed in m/s or None for "no fix") of one NMEA line.

    Lines that are not RMC/VTG, or fail their checksum, give ``(False, None)``.
    """
    try:
        sentence = parse_sentence(line)
        if sentence.kind == "RMC":
            rmc = parse_rmc(sentence)
            return True, rmc.speed_mps if rmc.valid else None
        if sentence.kind == "VTG":
            vtg = parse_vtg(sentence)
            if vtg.mode == "N" or vtg.speed_kmh is None:
                return True, None
            return True, vtg.speed_kmh / 3.6
    except NmeaError:
        pass
    return False, None


class NmeaPort:
    """The GNSS serial port, read without blocking (pyserial, ``timeout=0``)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.port: serial.Serial | None = serial.Serial(path, baudrate=115200, timeout=0)
        self._pending = b""
        self.error: str | None = None

    def poll(self) -> list[float | None]:
        """Speeds (m/s, or None for "no fix") of the RMC/VTG sentences received since the last
        call. A port that fails is closed and gives nothing more (``error`` says why)."""
        if self.port is None:
            return []
        try:
            data = self.port.read(4096)
        except (serial.SerialException, OSError) as exc:
            self.error = f"{self.path}: {exc}"
            self.close()
            return []
        if not data:
            return []
        *lines, self._pending = (self._pending + data).split(b"\n")
        out = []
        for line in lines:
            is_speed, value = nmea_speed(line)
            if is_speed:
                out.append(value)
        return out

    def close(self) -> None:
        if self.port is not None:
            try:
                self.port.close()
            finally:
                self.port = None
