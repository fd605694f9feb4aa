"""NMEA 0183 for the BeiDou speed module: sentence builders, a checked parser, a receiver model.

Sentences (NMEA 0183 v4.00 field layout, as multi-GNSS receivers print them)::

    $GNRMC,hhmmss.ss,A,ddmm.mmmmm,N,dddmm.mmmmm,E,sog_kn,cog,ddmmyy,,,A*hh
    $GNVTG,cog,T,,M,sog_kn,N,sog_kmh,K,A*hh
    $GNGGA,hhmmss.ss,ddmm.mmmmm,N,dddmm.mmmmm,E,1,nn,hdop,alt,M,sep,M,,*hh

The talker is ``GN`` (a fix from BeiDou and GPS together, what a dual-system "BeiDou module"
prints) unless the rig config says ``BD`` (BeiDou only, NMEA 4.0 Chinese extension), ``GB``
(BeiDou in NMEA 4.11) or ``GP``. Without a fix the receiver keeps printing, with empty fields::

    $GNRMC,hhmmss.ss,V,,,,,,,ddmmyy,,,N*hh
    $GNVTG,,,,,,,,,N*hh
    $GNGGA,hhmmss.ss,,,,,0,00,99.99,,,,,,*hh

The checksum is the XOR of every character between ``$`` and ``*``, two upper-case hex digits.

Example
-------
>>> s = build_sentence("GN", "VTG", ["90.00", "T", "", "M", "2.160", "N", "4.000", "K", "A"])
>>> s
'$GNVTG,90.00,T,,M,2.160,N,4.000,K,A*1B\\r\\n'
>>> parse_sentence(s).fields[6]
'4.000'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np

from hil.errors import HilError
from plant_emulators.sowing_depth.config import GnssConfig

__all__ = [
    "KNOTS_PER_MPS",
    "GgaData",
    "GnssFix",
    "GnssReceiver",
    "NmeaError",
    "NmeaSentence",
    "RmcData",
    "VtgData",
    "build_gga",
    "build_rmc",
    "build_sentence",
    "build_vtg",
    "checksum",
    "parse_gga",
    "parse_rmc",
    "parse_sentence",
    "parse_vtg",
]

#: 1 m/s in knots (1 kn = 1852 m/h).
KNOTS_PER_MPS = 3600.0 / 1852.0
_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3


class NmeaError(HilError, ValueError):
    """A sentence is malformed or its checksum is wrong."""


def checksum(body: str) -> str:
    """XOR of the characters of ``body`` (between ``$`` and ``*``) as two hex digits."""
    value = 0
    for ch in body:
        value ^= ord(ch)
    return f"{value:02X}"


def build_sentence(talker: str, kind: str, fields: list[str]) -> str:
    """``$<talker><kind>,<fields>*<checksum>\\r\\n``."""
    body = f"{talker}{kind}," + ",".join(fields)
    return f"${body}*{checksum(body)}\r\n"


@dataclass(frozen=True)
class NmeaSentence:
    """A parsed sentence with a verified checksum."""

    talker: str
    kind: str
    fields: tuple[str, ...]


def parse_sentence(line: str | bytes) -> NmeaSentence:
    """Parse one sentence, verifying its checksum.

    Raises
    ------
    NmeaError
        If the line does not start with ``$``, has no ``*hh`` checksum, or the checksum does not
        match (the message gives both values).
    """
    if isinstance(line, bytes):
        try:
            line = line.decode("ascii")
        except UnicodeDecodeError as exc:
            raise NmeaError(f"not ASCII: {line!r}") from exc
    text = line.strip()
    if not text.startswith("$"):
        raise NmeaError(f"sentence does not start with '$': {text!r}")
    body, star, given = text[1:].rpartition("*")
    if not star or len(given) != 2:
        raise NmeaError(f"sentence has no '*hh' checksum: {text!r}")
    expected = checksum(body)
    if given.upper() != expected:
        raise NmeaError(f"checksum mismatch in {text!r}: got {given}, computed {expected}")
    head, *fields = body.split(",")
    if len(head) != 5:
        raise NmeaError(f"bad address field {head!r} in {text!r}")
    return NmeaSentence(talker=head[:2], kind=head[2:], fields=tuple(fields))


# ---------------------------------------------------------------------- builders
@dataclass(frozen=True)
class GnssFix:
    """What a receiver knows at one epoch."""

    utc: datetime
    valid: bool
    latitude_deg: float = 0.0
    longitude_deg: float = 0.0
    speed_mps: float = 0.0
    course_deg: float = 0.0
    altitude_m: float = 0.0
    geoid_separation_m: float = 0.0
    satellites: int = 0
    hdop: float = 99.99
    quality: int = 1


def _time(utc: datetime) -> str:
    return f"{utc:%H%M%S}.{utc.microsecond // 10000:02d}"


def _lat(lat: float) -> tuple[str, str]:
    hemi = "N" if lat >= 0 else "S"
    lat = abs(lat)
    deg = int(lat)
    minutes = (lat - deg) * 60.0
    if round(minutes, 5) >= 60.0:
        deg, minutes = deg + 1, 0.0
    return f"{deg:02d}{minutes:08.5f}", hemi


def _lon(lon: float) -> tuple[str, str]:
    hemi = "E" if lon >= 0 else "W"
    lon = abs(lon)
    deg = int(lon)
    minutes = (lon - deg) * 60.0
    if round(minutes, 5) >= 60.0:
        deg, minutes = deg + 1, 0.0
    return f"{deg:03d}{minutes:08.5f}", hemi


def build_rmc(talker: str, fix: GnssFix) -> str:
    """RMC: time, status, position, speed over ground (knots), course, date, mode."""
    date = f"{fix.utc:%d%m%y}"
    if not fix.valid:
        return build_sentence(talker, "RMC", [_time(fix.utc), "V", "", "", "", "", "", "",
                                              date, "", "", "N"])
    lat, ns = _lat(fix.latitude_deg)
    lon, ew = _lon(fix.longitude_deg)
    return build_sentence(talker, "RMC", [
        _time(fix.utc), "A", lat, ns, lon, ew, f"{fix.speed_mps * KNOTS_PER_MPS:.3f}",
        f"{fix.course_deg % 360.0:.2f}", date, "", "", "A"])


def build_vtg(talker: str, fix: GnssFix) -> str:
    """VTG: course over ground and speed over ground in knots and km/h."""
    if not fix.valid:
        return build_sentence(talker, "VTG", ["", "", "", "", "", "", "", "", "N"])
    return build_sentence(talker, "VTG", [
        f"{fix.course_deg % 360.0:.2f}", "T", "", "M", f"{fix.speed_mps * KNOTS_PER_MPS:.3f}",
        "N", f"{fix.speed_mps * 3.6:.3f}", "K", "A"])


def build_gga(talker: str, fix: GnssFix) -> str:
    """GGA: time, position, fix quality, satellites used, HDOP, altitude, geoid separation."""
    if not fix.valid:
        return build_sentence(talker, "GGA", [_time(fix.utc), "", "", "", "", "0", "00",
                                              "99.99", "", "", "", "", "", ""])
    lat, ns = _lat(fix.latitude_deg)
    lon, ew = _lon(fix.longitude_deg)
    return build_sentence(talker, "GGA", [
        _time(fix.utc), lat, ns, lon, ew, str(fix.quality), f"{fix.satellites:02d}",
        f"{fix.hdop:.2f}", f"{fix.altitude_m:.1f}", "M", f"{fix.geoid_separation_m:.1f}", "M",
        "", ""])


# ---------------------------------------------------------------------- typed parsing
@dataclass(frozen=True)
class RmcData:
    """Content of an RMC sentence (None where the field is empty)."""

    time_utc: str
    valid: bool
    latitude_deg: float | None
    longitude_deg: float | None
    speed_knots: float | None
    course_deg: float | None
    date: str
    mode: str

    @property
    def speed_mps(self) -> float | None:
        """Speed over ground in m/s."""
        return None if self.speed_knots is None else self.speed_knots / KNOTS_PER_MPS


@dataclass(frozen=True)
class VtgData:
    """Content of a VTG sentence."""

    course_deg: float | None
    speed_knots: float | None
    speed_kmh: float | None
    mode: str


@dataclass(frozen=True)
class GgaData:
    """Content of a GGA sentence."""

    time_utc: str
    latitude_deg: float | None
    longitude_deg: float | None
    quality: int
    satellites: int
    hdop: float | None
    altitude_m: float | None
    geoid_separation_m: float | None


def _float(text: str) -> float | None:
    return float(text) if text else None


def _coordinate(value: str, hemi: str, degree_digits: int) -> float | None:
    if not value:
        return None
    deg = int(value[:degree_digits])
    minutes = float(value[degree_digits:])
    result = deg + minutes / 60.0
    return -result if hemi in ("S", "W") else result


def _expect(sentence: NmeaSentence, kind: str, n_fields: int) -> None:
    if sentence.kind != kind:
        raise NmeaError(f"expected a {kind} sentence, got {sentence.kind}")
    if len(sentence.fields) < n_fields:
        raise NmeaError(f"{kind} has {len(sentence.fields)} fields, expected {n_fields}")


def parse_rmc(line: str | bytes | NmeaSentence) -> RmcData:
    """Parse and check an RMC sentence."""
    s = line if isinstance(line, NmeaSentence) else parse_sentence(line)
    _expect(s, "RMC", 12)
    f = s.fields
    try:
        return RmcData(time_utc=f[0], valid=f[1] == "A", latitude_deg=_coordinate(f[2], f[3], 2),
                       longitude_deg=_coordinate(f[4], f[5], 3), speed_knots=_float(f[6]),
                       course_deg=_float(f[7]), date=f[8], mode=f[11])
    except ValueError as exc:
        raise NmeaError(f"bad RMC field: {exc}") from exc


def parse_vtg(line: str | bytes | NmeaSentence) -> VtgData:
    """Parse and check a VTG sentence."""
    s = line if isinstance(line, NmeaSentence) else parse_sentence(line)
    _expect(s, "VTG", 9)
    f = s.fields
    try:
        return VtgData(course_deg=_float(f[0]), speed_knots=_float(f[4]), speed_kmh=_float(f[6]),
                       mode=f[8])
    except ValueError as exc:
        raise NmeaError(f"bad VTG field: {exc}") from exc


def parse_gga(line: str | bytes | NmeaSentence) -> GgaData:
    """Parse and check a GGA sentence."""
    s = line if isinstance(line, NmeaSentence) else parse_sentence(line)
    _expect(s, "GGA", 14)
    f = s.fields
    try:
        return GgaData(time_utc=f[0], latitude_deg=_coordinate(f[1], f[2], 2),
                       longitude_deg=_coordinate(f[3], f[4], 3), quality=int(f[5] or 0),
                       satellites=int(f[6] or 0), hdop=_float(f[7]), altitude_m=_float(f[8]),
                       geoid_separation_m=_float(f[10]))
    except ValueError as exc:
        raise NmeaError(f"bad GGA field: {exc}") from exc


# ---------------------------------------------------------------------- receiver model
class GnssReceiver:
    """A GNSS speed module riding on the tractor: one RMC, VTG, GGA triple per epoch.

    The antenna advances from the configured start along ``heading_deg`` by the distance the
    plant reports; latitude/longitude follow from the WGS84 radii of curvature at the start
    (flat-earth over a field). Speed over ground gets white noise of ``speed_noise_sd_m_per_s``;
    the position gets a first-order Gauss-Markov error (60 s correlation) of
    ``position_noise_sd_m`` per axis, as standalone fixes wander.

    Parameters
    ----------
    config : GnssConfig
        Talker, start point, heading, quality figures, noise.
    rng : numpy.random.Generator
        The receiver's own generator.

    Attributes
    ----------
    fix_lost : bool
        Fault hook: no fix (RMC status V, GGA quality 0, empty fields).
    """

    _POSITION_CORRELATION_S = 60.0

    def __init__(self, config: GnssConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._rng = rng
        try:
            start = datetime.fromisoformat(config.start_utc.replace("Z", "+00:00"))
        except ValueError as exc:
            raise NmeaError(f"gnss.start_utc is not an ISO 8601 time: {config.start_utc!r}") \
                from exc
        self._start = start.astimezone(UTC) if start.tzinfo else start.replace(tzinfo=UTC)
        lat = math.radians(config.start_latitude_deg)
        w = math.sqrt(1.0 - _WGS84_E2 * math.sin(lat) ** 2)
        self._m_per_deg_lat = math.radians(1.0) * _WGS84_A * (1.0 - _WGS84_E2) / w**3
        self._m_per_deg_lon = math.radians(1.0) * _WGS84_A * math.cos(lat) / w
        self._err_n = self._err_e = 0.0
        self._last_time_s: float | None = None
        self.fix_lost = False

    def fix(self, time_s: float, distance_m: float, speed_mps: float) -> GnssFix:
        """The receiver's solution at simulated time ``time_s``."""
        c = self.config
        utc = self._start + timedelta(seconds=time_s)
        noise = self._rng.standard_normal(3)
        sd = c.position_noise_sd_m
        if self._last_time_s is None:
            # Start in the stationary distribution of the error.
            self._err_n = sd * float(noise[0])
            self._err_e = sd * float(noise[1])
        else:
            a = math.exp(-max(0.0, time_s - self._last_time_s) / self._POSITION_CORRELATION_S)
            b = sd * math.sqrt(1.0 - a * a)
            self._err_n = a * self._err_n + b * float(noise[0])
            self._err_e = a * self._err_e + b * float(noise[1])
        self._last_time_s = time_s
        if self.fix_lost:
            return GnssFix(utc=utc, valid=False)
        heading = math.radians(c.heading_deg)
        north = distance_m * math.cos(heading) + self._err_n
        east = distance_m * math.sin(heading) + self._err_e
        speed = max(0.0, speed_mps + c.speed_noise_sd_m_per_s * float(noise[2]))
        return GnssFix(
            utc=utc, valid=True,
            latitude_deg=c.start_latitude_deg + north / self._m_per_deg_lat,
            longitude_deg=c.start_longitude_deg + east / self._m_per_deg_lon,
            speed_mps=speed, course_deg=c.heading_deg, altitude_m=c.altitude_m,
            geoid_separation_m=c.geoid_separation_m, satellites=c.satellites_used,
            hdop=c.hdop, quality=1)

    def epoch(self, time_s: float, distance_m: float, speed_mps: float) -> list[str]:
        """RMC, VTG and GGA sentences for one epoch."""
        fix = self.fix(time_s, distance_m, speed_mps)
        talker = self.config.talker_id
        return [build_rmc(talker, fix), build_vtg(talker, fix), build_gga(talker, fix)]
