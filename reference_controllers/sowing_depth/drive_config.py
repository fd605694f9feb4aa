"""What a CANopen master writes to its CiA 402 drive at boot: the drive's PDOs, by SDO.

A commercial controller does not use its drive's default PDOs (CiA 301's pre-defined
connection set, whatever the EDS says): it maps the objects it needs into the PDOs it wants, at
the COB-IDs, transmission types, event timers and inhibit times of its own CAN layout, and its
database describes the frames that result. :class:`PdoConfig` is one such PDO, named by the
database message it becomes; :func:`configuration_writes` is the whole boot-time sequence in
CiA 301's re-mapping order (every PDO invalidated first, bit 31 of its COB-ID, so that a COB-ID
can move from one PDO to another; then per PDO: mapping count 0, the entries, the count,
transmission type, inhibit time, event timer, the COB-ID with bit 31 clear), followed by the
application objects (a mode of operation, the heartbeat producer time).
:func:`check_against_database` holds the database's frames to the mapping, so the two cannot
drift apart. :class:`SdoBatch` sends the writes as expedited SDO downloads and checks the
drive's confirmations; an abort says which object the drive refused and with which code.

Sizes are CiA 301's and CiA 402's data types (COB-IDs and mapping entries UNSIGNED32,
transmission type and mapping count UNSIGNED8, inhibit time, event timer and heartbeat time
UNSIGNED16, modes of operation INTEGER8): a master writes them from the standard, not from the
drive's EDS.

>>> pdo = PdoConfig("rpdo", 1, "Cmd", ((0x60FF, 0, 32), (0x6040, 0, 16)), 1)
>>> [f"{i:04X}:{s} {v:X}" for i, s, v, _ in pdo.writes(0x302)]
['1600:0 0', '1600:1 60FF0020', '1600:2 60400010', '1600:0 2', '1400:2 1', '1400:1 302']
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import can

__all__ = ["NOT_VALID", "PdoConfig", "SdoBatch", "Write", "check_against_database",
           "configuration_writes", "default_cob_id"]

#: bit 31 of a PDO COB-ID: the PDO does not exist (CiA 301)
NOT_VALID = 0x80000000
#: (index, sub-index, value, size in bytes) of one SDO download
Write = tuple[int, int, int, int]
#: expedited download command specifiers by size (CiA 301: ccs 1, e = s = 1, n = 4 - size)
_DOWNLOAD_CCS = {1: 0x2F, 2: 0x2B, 4: 0x23}
_DOWNLOAD_CONFIRMED, _ABORT = 0x60, 0x80


def default_cob_id(kind: Literal["rpdo", "tpdo"], number: int, node_id: int) -> int:
    """CiA 301's pre-defined COB-ID of PDO ``number`` (1-4) of ``node_id``.

    >>> hex(default_cob_id("rpdo", 2, 2)), hex(default_cob_id("tpdo", 1, 2))
    ('0x302', '0x182')
    """
    base = 0x200 if kind == "rpdo" else 0x180
    return base + 0x100 * (number - 1) + node_id


@dataclass(frozen=True)
class PdoConfig:
    """One PDO of the drive as the master configures it.

    Parameters
    ----------
    kind : {"rpdo", "tpdo"}
        Received by the drive (the master's command) or sent by it.
    number : int
        The PDO's number, 1 first (communication object 0x1400/0x1800 + number - 1).
    message : str
        The database message the PDO becomes (its id is the COB-ID).
    objects : tuple of (index, sub-index, bits)
        The mapped objects, in frame order from byte 0.
    transmission_type : int
        1-240: every n-th SYNC; 254/255: event-driven.
    event_timer_ms : int
        TPDOs of type 254/255: the period (0: none).
    inhibit_100us : int
        TPDOs: the least time between two frames, in 100 µs.
    """

    kind: Literal["rpdo", "tpdo"]
    number: int
    message: str
    objects: tuple[tuple[int, int, int], ...]
    transmission_type: int
    event_timer_ms: int = 0
    inhibit_100us: int = 0

    @property
    def communication_index(self) -> int:
        return (0x1400 if self.kind == "rpdo" else 0x1800) + self.number - 1

    @property
    def mapping_index(self) -> int:
        return self.communication_index + 0x200

    def writes(self, cob_id: int) -> list[Write]:
        """Mapping, then communication parameters, then the COB-ID made valid (the PDO must
        already be invalid)."""
        com, mapping = self.communication_index, self.mapping_index
        out: list[Write] = [(mapping, 0, 0, 1)]
        out += [(mapping, sub, (index << 16) | (subindex << 8) | bits, 4)
                for sub, (index, subindex, bits) in enumerate(self.objects, 1)]
        out += [(mapping, 0, len(self.objects), 1), (com, 2, self.transmission_type, 1)]
        if self.kind == "tpdo":
            out += [(com, 3, self.inhibit_100us, 2), (com, 5, self.event_timer_ms, 2)]
        out.append((com, 1, cob_id, 4))
        return out


def configuration_writes(pdos: Sequence[PdoConfig], cob_ids: dict[str, int], node_id: int, *,
                         pdo_count: int = 3, application: Sequence[Write] = ()) -> list[Write]:
    """The boot-time writes: every PDO (``pdo_count`` of each kind) invalidated, the configured
    ones mapped and made valid at ``cob_ids[pdo.message]``, then ``application`` writes.

    A PDO not in ``pdos`` stays invalid: the master does not use it.
    """
    out: list[Write] = []
    for kind in ("rpdo", "tpdo"):
        base = 0x1400 if kind == "rpdo" else 0x1800
        for number in range(1, pdo_count + 1):
            cob = default_cob_id(kind, number, node_id)       # type: ignore[arg-type]
            out.append((base + number - 1, 1, NOT_VALID | cob, 4))
    for pdo in pdos:
        out += pdo.writes(cob_ids[pdo.message])
    out += list(application)
    return out


def check_against_database(pdos: Sequence[PdoConfig], db: Any) -> dict[str, int]:
    """The COB-ID of every configured PDO (its message's id), after holding the message to
    the mapping: standard id, little-endian signals packed from bit 0 in the mapped order with
    the mapped lengths, and the frame exactly as long as the mapping (CiA 301 PDOs).

    Raises
    ------
    ValueError
        The database's frame is not what the mapping makes (naming the message and why).
    """
    ids: dict[str, int] = {}
    for pdo in pdos:
        msg = db.get_message_by_name(pdo.message)
        if msg.is_extended_frame or msg.frame_id > 0x7FF:
            raise ValueError(f"{pdo.message}: a PDO has an 11-bit COB-ID, not "
                             f"0x{msg.frame_id:X}")
        signals = sorted(msg.signals, key=lambda s: s.start)
        layout = [(s.start, s.length, s.byte_order) for s in signals]
        want, bit = [], 0
        for _, _, bits in pdo.objects:
            want.append((bit, bits, "little_endian"))
            bit += bits
        if layout != want or msg.length != (bit + 7) // 8:
            raise ValueError(f"{pdo.message}: the database's frame {layout} ({msg.length} "
                             f"bytes) is not the {pdo.kind.upper()}{pdo.number} mapping {want} "
                             f"({(bit + 7) // 8} bytes)")
        ids[pdo.message] = int(msg.frame_id)
    return ids


class SdoBatch:
    """Expedited SDO downloads to one node, sent back to back, their confirmations checked.

    The node's SDO server answers requests in the order they come, so the n-th answer is the
    n-th request's. A strict CiA 301 client sends the next request only on the last one's
    confirmation; sending them together keeps every frame of the master a direct answer to
    the node's boot-up, as lockstep asks (a chain of request, confirmation, request would put
    the master's frames between the rig's steps: ``docs/guide/clocks.md``).

    Parameters
    ----------
    request, response : cantools message
        The node's SDO request (0x600 + node) and response (0x580 + node) frames, with the
        signals ``Command``, ``Index``, ``SubIndex`` and ``Data``.
    writes : sequence of Write
        What to download, in order.
    """

    def __init__(self, request: Any, response: Any, writes: Sequence[Write]) -> None:
        self.request, self.response = request, response
        self.writes = list(writes)
        #: writes confirmed so far
        self.confirmed = 0
        #: why the node refused (None while it accepts)
        self.error: str | None = None

    @property
    def done(self) -> bool:
        """Every write confirmed."""
        return self.confirmed >= len(self.writes) and self.error is None

    @property
    def pending(self) -> bool:
        """Answers are still due (and none refused)."""
        return self.confirmed < len(self.writes) and self.error is None

    def frames(self) -> list[can.Message]:
        """Every request, in order."""
        return [self._frame(write) for write in self.writes]

    def on_response(self, data: bytes) -> None:
        """Take the node's next answer: a confirmation, or an abort (kept in :attr:`error`)."""
        if not self.pending:
            return
        answer = self.response.decode(bytes(data), decode_choices=False)
        index, subindex, value, _ = self.writes[self.confirmed]
        if (int(answer["Index"]), int(answer["SubIndex"])) != (index, subindex):
            self.error = (f"0x{index:04X}:{subindex:02X}: answered for "
                          f"0x{int(answer['Index']):04X}:{int(answer['SubIndex']):02X}")
        elif int(answer["Command"]) == _ABORT:
            self.error = (f"0x{index:04X}:{subindex:02X} = 0x{value:X} refused (SDO abort "
                          f"0x{int(answer['Data']):08X})")
        elif int(answer["Command"]) == _DOWNLOAD_CONFIRMED:
            self.confirmed += 1
        else:
            self.error = (f"0x{index:04X}:{subindex:02X}: unexpected answer "
                          f"0x{int(answer['Command']):02X}")

    def _frame(self, write: Write) -> can.Message:
        index, subindex, value, size = write
        data = self.request.encode({"Command": _DOWNLOAD_CCS[size], "Index": index,
                                    "SubIndex": subindex,
                                    "Data": value & ((1 << (8 * size)) - 1)})
        return can.Message(arbitration_id=self.request.frame_id, is_extended_id=False,
                           data=data)
