"""A run's frame log as numpy columns, read from the candump ``bus.log`` the recorder wrote.

The recorder keeps no frames in memory: it writes them to ``bus.log`` (candump ``-L`` lines,
``(12.345678) can0 0CFE49F0#0011223344556677 R``) as the run goes. Conformance reads that
file back once, vectorised: the line ends, the ``)`` and the ``#`` of every line are found
with numpy and the fixed-form fields (time stamp with six decimals, hexadecimal identifier,
payload, direction) are decoded as columns, without a Python loop over the frames (a
sowing-depth field run has ~120,000 lines).

A log with lines of another form (error frames, remote frames, CAN FD) is read line by line
instead; the result is the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.errors import ConfigError

_NL, _CLOSE, _HASH, _SPACE, _DOT = 10, ord(")"), ord("#"), 32, ord(".")


@dataclass(frozen=True)
class FrameLog:
    """Frames of one run, in log order.

    Attributes
    ----------
    time_s : ndarray of float64
        Run time of each frame (the rig's clock when it sent or received the frame).
    can_id : ndarray of int64
        Arbitration identifier.
    extended : ndarray of bool
        29-bit identifier.
    dlc : ndarray of int64
        Data length (bytes).
    rx : ndarray of bool
        True: received by the rig (sent by the DUT or another node); False: sent by the rig.
    data : ndarray of uint8, shape (n, 8)
        Payload, zero-padded to 8 bytes.
    """

    time_s: np.ndarray
    can_id: np.ndarray
    extended: np.ndarray
    dlc: np.ndarray
    rx: np.ndarray
    data: np.ndarray

    def __len__(self) -> int:
        return int(self.time_s.size)

    def select(self, mask: np.ndarray) -> FrameLog:
        """The frames where ``mask`` is True."""
        return FrameLog(self.time_s[mask], self.can_id[mask], self.extended[mask],
                        self.dlc[mask], self.rx[mask], self.data[mask])

    @classmethod
    def empty(cls) -> FrameLog:
        return cls(np.zeros(0), np.zeros(0, np.int64), np.zeros(0, bool),
                   np.zeros(0, np.int64), np.zeros(0, bool), np.zeros((0, 8), np.uint8))


#: ASCII → value of a hexadecimal digit (upper or lower case); anything else → 0
_HEX = np.zeros(256, dtype=np.uint8)
_HEX[ord("0"):ord("9") + 1] = np.arange(10)
_HEX[ord("A"):ord("F") + 1] = np.arange(10, 16)
_HEX[ord("a"):ord("f") + 1] = np.arange(10, 16)


def _right_aligned(buf: np.ndarray, end: np.ndarray, width: int,
                   start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``width`` bytes ending before ``end`` per line, and a mask of those at or after
    ``start`` (the rest lie before the field and count as absent)."""
    index = end[:, None] - width + np.arange(width)[None, :]
    valid = index >= start[:, None]
    return buf[np.clip(index, 0, buf.size - 1)], valid


def parse_candump(text: bytes, *, keep: str = "all") -> FrameLog:
    """The frames of a candump ``-L`` log (as python-can's ``CanutilsLogWriter`` writes it).

    ``keep``: ``"all"`` frames, or ``"rx+sync"``: only the frames the rig received and the
    SYNC frames (0x080) it sent, which is all conformance needs (about half a run's lines are
    the rig's own sensor frames, and they are never decoded).

    Raises
    ------
    ConfigError
        A line that is not a candump frame line (named by its number).

    Examples
    --------
    >>> log = parse_candump(b"(0.100000) can0 710#05 R\\n(12.500000) can0 0CFE49F0#0102 T\\n")
    >>> log.can_id.tolist(), log.extended.tolist(), log.dlc.tolist(), log.rx.tolist()
    ([1808, 217991664], [False, True], [1, 2], [True, False])
    >>> log.time_s.tolist()
    [0.1, 12.5]
    """
    if keep not in ("all", "rx+sync"):
        raise ValueError(f"keep must be 'all' or 'rx+sync', got {keep!r}")
    if not text:
        return FrameLog.empty()
    if not text.endswith(b"\n"):
        text += b"\n"
    buf = np.frombuffer(text, dtype=np.uint8)
    ends = np.flatnonzero(buf == _NL)
    closes = np.flatnonzero(buf == _CLOSE)
    hashes = np.flatnonzero(buf == _HASH)
    n = ends.size
    regular = (closes.size == n and hashes.size == n and n > 0
               and bool(np.all(closes < hashes)) and bool(np.all(hashes < ends))
               and bool(np.all(buf[ends - 2] == _SPACE)) and bool(np.all(closes >= 8)))
    if regular:
        starts = np.concatenate(([0], ends[:-1] + 1))
        # the identifier (3 or 8 hex digits) follows the space after the channel name
        id_len = np.where(buf[hashes - 4] == _SPACE, 3, 8)
        payload_len = ends - 2 - (hashes + 1)
        regular = (bool(np.all(buf[starts] == ord("(")))
                   and bool(np.all(buf[hashes - id_len - 1] == _SPACE))
                   and bool(np.all((payload_len % 2 == 0) & (payload_len <= 16)
                                   & (payload_len >= 0)))
                   and bool(np.all(buf[closes - 7] == _DOT)))
    if not regular:
        log = _parse_lines(text)
        if keep == "all":
            return log
        return log.select(log.rx | ((log.can_id == 0x080) & ~log.extended))
    rx = buf[ends - 1] == ord("R")
    if keep == "rx+sync":
        sync = ((id_len == 3) & (buf[hashes - 3] == ord("0")) & (buf[hashes - 2] == ord("8"))
                & (buf[hashes - 1] == ord("0")))
        wanted = rx | sync
        starts, ends, closes, hashes = starts[wanted], ends[wanted], closes[wanted], \
            hashes[wanted]
        id_len, payload_len, rx = id_len[wanted], payload_len[wanted], rx[wanted]
    # identifier: up to 8 hex digits right-aligned before '#'
    chars, valid = _right_aligned(buf, hashes, 8, hashes - id_len)
    digits = np.where(valid, _HEX[chars], 0).astype(np.int64)
    can_id = (digits << (4 * np.arange(7, -1, -1))[None, :]).sum(axis=1)
    # time stamp: integer digits before the '.', six decimals after it
    int_chars, int_valid = _right_aligned(buf, closes - 7, 12, starts + 1)
    int_digits = np.where(int_valid, int_chars - ord("0"), 0).astype(np.int64)
    seconds = int_digits @ (10 ** np.arange(11, -1, -1, dtype=np.int64))
    frac_chars, _ = _right_aligned(buf, closes, 6, closes - 6)
    micros = (frac_chars - ord("0")).astype(np.int64) @ (10 ** np.arange(5, -1, -1,
                                                                          dtype=np.int64))
    time_s = seconds + micros / 1e6
    # payload: 2 hex digits per byte after '#'
    dlc = payload_len // 2
    index = hashes[:, None] + 1 + np.arange(16)[None, :]
    present = np.arange(16)[None, :] < payload_len[:, None]
    nibbles = np.where(present, _HEX[buf[np.minimum(index, buf.size - 1)]], 0)
    data = (nibbles[:, 0::2] << 4) | nibbles[:, 1::2]
    return FrameLog(time_s.astype(np.float64), can_id, id_len == 8, dlc.astype(np.int64), rx,
                    data.astype(np.uint8))


def _parse_lines(text: bytes) -> FrameLog:
    """Line by line: logs with error, remote or CAN FD frames (rare; never the rig's own)."""
    times, ids, ext, dlcs, rxs, datas = [], [], [], [], [], []
    for number, line in enumerate(text.decode("ascii", "replace").splitlines(), 1):
        if not line.strip():
            continue
        try:
            stamp, _, frame, *rest = line.split()
            head, _, payload = frame.partition("#")
            if payload.startswith(("R", "#")):      # remote or CAN FD: not a data frame
                continue
            raw = bytes.fromhex(payload)
            times.append(float(stamp.strip("()")))
            ids.append(int(head, 16))
            ext.append(len(head) == 8)
            dlcs.append(len(raw))
            rxs.append(bool(rest) and rest[0] == "R")
            datas.append(raw[:8].ljust(8, b"\0"))
        except ValueError as exc:
            raise ConfigError(f"line {number} is not a candump frame: {line[:80]!r}") from exc
    if not times:
        return FrameLog.empty()
    return FrameLog(np.array(times), np.array(ids, np.int64), np.array(ext, bool),
                    np.array(dlcs, np.int64), np.array(rxs, bool),
                    np.frombuffer(b"".join(datas), np.uint8).reshape(-1, 8).copy())


def read_bus_log(path: str | Path, *, keep: str = "all") -> FrameLog:
    """The frames of the candump log at ``path`` (``keep`` as :func:`parse_candump`).

    Raises
    ------
    ConfigError
        The file cannot be read, or a line is not a candump frame (the path is named).
    """
    path = Path(path)
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read the bus log: {exc.strerror or exc}",
                          path=str(path)) from exc
    try:
        return parse_candump(text, keep=keep)
    except ConfigError as exc:
        raise ConfigError(str(exc), path=str(path)) from exc
