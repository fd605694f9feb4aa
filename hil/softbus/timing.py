"""CAN frame length in bits, and arbitration by identifier.

A paced software bus must hold each frame for as long as the wire would: the bit count of a
classic CAN data frame including the stuff bits its content actually produces (ISO 11898-1:
after five equal bits the transmitter inserts one of opposite value, from SOF to the end of
the CRC), plus the fixed-form tail (CRC delimiter, ACK slot and delimiter, EOF) and the
3-bit intermission. The worst case is also given, because bus-load budgets are quoted that way.

When several frames wait for the bus, the one with the lowest arbitration field wins:
identifier bits first, and an 11-bit frame beats a 29-bit one with the same base identifier
(its RTR bit is dominant where the extended frame sends a recessive SRR).
"""

from __future__ import annotations

from functools import lru_cache

_CRC15_POLY = 0x4599
# CRC delimiter (1) + ACK slot (1) + ACK delimiter (1) + EOF (7) + intermission (3)
_TAIL_BITS = 13
ERROR_FRAME_BITS = 14 + 8 + 3  # error flag (6 + up to 6 echoed, take 6+8 worst) + delimiter + IFS


def _header_bits(can_id: int, extended: bool, dlc: int) -> list[int]:
    bits = [0]  # SOF
    if extended:
        base, ext = can_id >> 18, can_id & 0x3FFFF
        bits += [(base >> i) & 1 for i in range(10, -1, -1)]
        bits += [1, 1]  # SRR, IDE
        bits += [(ext >> i) & 1 for i in range(17, -1, -1)]
        bits += [0, 0, 0]  # RTR (data frame), r1, r0
    else:
        bits += [(can_id >> i) & 1 for i in range(10, -1, -1)]
        bits += [0, 0, 0]  # RTR, IDE, r0
    bits += [(dlc >> i) & 1 for i in range(3, -1, -1)]
    return bits


def _crc15(bits: list[int]) -> int:
    crc = 0
    for bit in bits:
        nxt = bit ^ ((crc >> 14) & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= _CRC15_POLY
    return crc


def _count_stuff_bits(bits: list[int]) -> int:
    stuffed = 0
    run_value = bits[0]
    run_length = 1
    for bit in bits[1:]:
        if bit == run_value:
            run_length += 1
            if run_length == 5:
                stuffed += 1
                # the stuff bit has the opposite value and starts a new run
                run_value = 1 - bit
                run_length = 1
        else:
            run_value = bit
            run_length = 1
    return stuffed


@lru_cache(maxsize=4096)
def frame_bits(can_id: int, extended: bool, data: bytes) -> int:
    """Exact bits on the wire for a classic data frame, stuffing and intermission included.

    >>> frame_bits(0x000, False, bytes(8))  # all-dominant content stuffs heavily
    127
    >>> frame_bits(0x18FEF100, True, bytes(8)) <= worst_case_frame_bits(True, 8)
    True
    """
    bits = _header_bits(can_id, extended, len(data))
    for byte in data:
        bits += [(byte >> i) & 1 for i in range(7, -1, -1)]
    crc = _crc15(bits)
    bits += [(crc >> i) & 1 for i in range(14, -1, -1)]
    return len(bits) + _count_stuff_bits(bits) + _TAIL_BITS


def worst_case_frame_bits(extended: bool, dlc: int) -> int:
    """Worst-case bits (maximum stuffing) for a data frame of ``dlc`` bytes.

    >>> worst_case_frame_bits(True, 8), worst_case_frame_bits(False, 8)
    (160, 135)
    """
    stuffable = (54 if extended else 34) + 8 * dlc
    return stuffable + (stuffable - 1) // 4 + _TAIL_BITS


def arbitration_key(can_id: int, extended: bool) -> tuple[int, int, int]:
    """Sort key: the frame with the smallest key wins arbitration."""
    if extended:
        return (can_id >> 18, 1, can_id & 0x3FFFF)
    return (can_id, 0, 0)
