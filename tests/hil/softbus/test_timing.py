"""Frame bit counts checked against an independent encoder: build the stuffed wire bits,
then check that destuffing gives back the frame and that the CRC verifies."""

from __future__ import annotations

import random

import pytest

from hil.softbus.timing import (
    _crc15,
    _header_bits,
    arbitration_key,
    frame_bits,
    worst_case_frame_bits,
)


def _stuff(bits: list[int]) -> list[int]:
    out, run_value, run = [], None, 0
    for bit in bits:
        out.append(bit)
        run = run + 1 if bit == run_value else 1
        run_value = bit
        if run == 5:
            out.append(1 - bit)
            run_value, run = 1 - bit, 1
    return out


def _destuff(bits: list[int]) -> list[int]:
    out, run_value, run, skip = [], None, 0, False
    for bit in bits:
        if skip:
            assert bit != run_value, "stuff bit must be the complement"
            skip, run_value, run = False, bit, 1
            continue
        out.append(bit)
        run = run + 1 if bit == run_value else 1
        run_value = bit
        if run == 5:
            skip = True
    return out


@pytest.mark.parametrize("seed", range(40))
def test_bit_count_matches_an_explicit_stuffed_encoding(seed: int) -> None:
    rng = random.Random(seed)
    extended = rng.random() < 0.5
    can_id = rng.randrange(1 << (29 if extended else 11))
    data = bytes(rng.choice([0x00, 0xFF, rng.randrange(256)]) for _ in range(rng.randrange(9)))
    body = _header_bits(can_id, extended, len(data))
    for byte in data:
        body += [(byte >> i) & 1 for i in range(7, -1, -1)]
    crc = _crc15(body)
    body_crc = body + [(crc >> i) & 1 for i in range(14, -1, -1)]
    assert _crc15(body_crc) == 0  # a CRC appended to its message checks to zero
    wire = _stuff(body_crc)
    assert _destuff(wire) == body_crc
    assert frame_bits(can_id, extended, data) == len(wire) + 13
    assert frame_bits(can_id, extended, data) <= worst_case_frame_bits(extended, len(data))


def test_worst_case_figures_match_published_frame_rates() -> None:
    # 250 kbit/s, 29-bit, 8 bytes: ~1,560 frames/s; 500 kbit/s 11-bit: ~3,700
    assert 250_000 / worst_case_frame_bits(True, 8) == pytest.approx(1562.5)
    assert 500_000 / worst_case_frame_bits(False, 8) == pytest.approx(3703.7, rel=1e-3)


def test_arbitration_order() -> None:
    keys = sorted([(arbitration_key(0x100, False), "std 0x100"),
                   (arbitration_key(0x100 << 18, True), "ext same base"),
                   (arbitration_key(0x0FF, False), "std 0x0ff"),
                   (arbitration_key((0x100 << 18) | 1, True), "ext base+1")])
    assert [name for _, name in keys] == ["std 0x0ff", "std 0x100", "ext same base", "ext base+1"]
