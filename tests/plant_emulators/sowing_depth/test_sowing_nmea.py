"""NMEA 0183 sentences of the GNSS speed module: checksums, builders, parser, receiver."""

from __future__ import annotations

import dataclasses
import math
from datetime import UTC, datetime

import numpy as np
import pytest

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.nmea import (
    KNOTS_PER_MPS,
    GnssFix,
    GnssReceiver,
    NmeaError,
    build_gga,
    build_rmc,
    build_vtg,
    checksum,
    parse_gga,
    parse_rmc,
    parse_sentence,
    parse_vtg,
)

FIX = GnssFix(utc=datetime(2022, 10, 15, 1, 30, 5, 250000, tzinfo=UTC), valid=True,
              latitude_deg=39.123456, longitude_deg=-116.5, speed_mps=1.111, course_deg=90.0,
              altitude_m=15.0, geoid_separation_m=-9.0, satellites=18, hdop=0.7)


def test_checksum_of_the_textbook_example() -> None:
    body = "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
    assert checksum(body) == "47"
    assert parse_sentence(f"${body}*47\r\n").kind == "GGA"


def test_rmc_round_trip() -> None:
    line = build_rmc("GN", FIX)
    assert line.startswith("$GNRMC,013005.25,A,3907.40736,N,11630.00000,W,")
    assert line.endswith("\r\n") and len(line) <= 82
    rmc = parse_rmc(line)
    assert rmc.valid and rmc.mode == "A" and rmc.date == "151022"
    assert rmc.latitude_deg == pytest.approx(39.123456, abs=1e-7)
    assert rmc.longitude_deg == pytest.approx(-116.5)
    assert rmc.speed_knots == pytest.approx(1.111 * KNOTS_PER_MPS, abs=5e-4)
    assert rmc.speed_mps == pytest.approx(1.111, abs=3e-4)
    assert rmc.course_deg == 90.0


def test_vtg_gives_speed_in_knots_and_km_per_h() -> None:
    vtg = parse_vtg(build_vtg("GN", FIX))
    assert vtg.speed_kmh == pytest.approx(4.0, abs=5e-4)
    assert vtg.speed_knots == pytest.approx(2.160, abs=5e-4)
    assert vtg.course_deg == 90.0 and vtg.mode == "A"


def test_gga_round_trip() -> None:
    line = build_gga("BD", FIX)
    assert line.startswith("$BDGGA,")
    gga = parse_gga(line)
    assert gga.quality == 1 and gga.satellites == 18 and gga.hdop == 0.7
    assert gga.altitude_m == 15.0 and gga.geoid_separation_m == -9.0
    assert gga.latitude_deg == pytest.approx(39.123456, abs=1e-7)


def test_fix_lost_prints_empty_fields_like_real_receivers() -> None:
    lost = GnssFix(utc=FIX.utc, valid=False)
    rmc, vtg, gga = build_rmc("GN", lost), build_vtg("GN", lost), build_gga("GN", lost)
    assert rmc.startswith("$GNRMC,013005.25,V,,,,,,,151022,,,N*")
    assert vtg.startswith("$GNVTG,,,,,,,,,N*")
    assert gga.startswith("$GNGGA,013005.25,,,,,0,00,99.99,,,,,,*")
    assert not parse_rmc(rmc).valid and parse_rmc(rmc).speed_mps is None
    assert parse_gga(gga).quality == 0 and parse_gga(gga).latitude_deg is None
    assert parse_vtg(vtg).speed_kmh is None


@pytest.mark.parametrize("corrupt", [
    lambda s: s.replace("*", "*0")[:-3] + "\r\n",        # three checksum digits
    lambda s: s.replace(",A,", ",V,", 1),                 # payload changed, checksum kept
    lambda s: s[:-4] + "00\r\n",                          # wrong checksum
    lambda s: s.split("*")[0] + "\r\n",                   # checksum missing
    lambda s: s[1:],                                      # no '$'
])
def test_corrupted_sentences_are_rejected(corrupt: object) -> None:
    line = build_rmc("GN", FIX)
    with pytest.raises(NmeaError):
        parse_sentence(corrupt(line))  # type: ignore[operator]


def test_checksum_error_names_both_values() -> None:
    line = build_vtg("GN", FIX)
    bad = line[:-4] + "00\r\n"
    with pytest.raises(NmeaError, match=r"got 00, computed [0-9A-F]{2}"):
        parse_sentence(bad)


def test_parsers_refuse_the_wrong_sentence() -> None:
    with pytest.raises(NmeaError, match="expected a GGA"):
        parse_gga(build_rmc("GN", FIX))


def test_receiver_advances_along_its_heading_at_the_plant_speed() -> None:
    cfg = dataclasses.replace(load_rig_config().gnss, position_noise_sd_m=0.0,
                              speed_noise_sd_m_per_s=0.0, heading_deg=45.0)
    rx = GnssReceiver(cfg, np.random.default_rng(0))
    start = parse_rmc(rx.epoch(0.0, 0.0, 1.5)[0])
    later = parse_rmc(rx.epoch(100.0, 150.0, 1.5)[0])
    assert later.time_utc == "013140.00" and start.time_utc == "013000.00"
    assert later.speed_mps == pytest.approx(1.5, abs=3e-4)
    m_lat = 111_030.0                       # m per degree of latitude near 39° N
    m_lon = m_lat * math.cos(math.radians(39.0))
    north = (later.latitude_deg - start.latitude_deg) * m_lat
    east = (later.longitude_deg - start.longitude_deg) * m_lon
    assert north == pytest.approx(150.0 / math.sqrt(2), rel=0.01)
    assert east == pytest.approx(150.0 / math.sqrt(2), rel=0.01)


def test_receiver_noise_is_seeded_and_fix_loss_is_a_hook() -> None:
    cfg = load_rig_config().gnss
    a = GnssReceiver(cfg, np.random.default_rng(5))
    b = GnssReceiver(cfg, np.random.default_rng(5))
    assert [a.epoch(t * 0.1, t * 0.111, 1.11) for t in range(20)] == \
        [b.epoch(t * 0.1, t * 0.111, 1.11) for t in range(20)]
    speeds = [parse_rmc(a.epoch(2 + t * 0.1, 0.0, 1.11)[0]).speed_mps for t in range(500)]
    assert np.std(speeds) == pytest.approx(cfg.speed_noise_sd_m_per_s, rel=0.2)
    a.fix_lost = True
    assert all(not parse_rmc(s).valid for s in a.epoch(60.0, 1.0, 1.0)[:1])
    assert parse_gga(a.epoch(60.1, 1.0, 1.0)[2]).quality == 0
    a.fix_lost = False
    assert parse_rmc(a.epoch(60.2, 1.0, 1.0)[0]).valid
